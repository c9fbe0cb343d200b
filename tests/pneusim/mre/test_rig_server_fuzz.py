"""The rig server as a safety function: no datagram takes it down, each kind of bad datagram is counted
and reported, a live session is not taken over, and the watchdog still drives the valve to its null.

Everything runs on 127.0.0.1 with a bounded number of datagrams (a few hundred).
"""

import signal
import socket
import struct
import subprocess
import time

import pytest

from pneusim.errors import PneusimError
from pneusim.mre.udp import BYE, CMD, FORMAT, HELLO, MEAS, READY, UdpPlant, pack, unpack
from pneusim.rig import load_rig

from mre_cases import rig_server_thread, serve_rig_process

NAN, INF = float("nan"), float("inf")
TS = 0.001        # paper1-mre's sample time


def _hello(position=0.02, command=5.0, t0=0.0, sample_time=TS, stamp=1.0):
    return pack(HELLO, 0, stamp, sample_time, position, command, t0)


@pytest.fixture
def served():
    """A server in a thread (watchdog 1 s, periodic report every 0.05 s into a list) and its thread."""
    reports = []
    with rig_server_thread(seed=1, watchdog_s=1.0, report=reports.append, report_interval_s=0.05) as (srv, thread):
        yield srv, thread, reports


def _socket():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(1.0)
    return s


def _wait(predicate, timeout=3.0):
    end = time.monotonic() + timeout
    while not predicate() and time.monotonic() < end:
        time.sleep(0.005)
    return predicate()


def _reply(s):
    try:
        return unpack(s.recv(256))
    except socket.timeout:
        return None


def test_no_datagram_takes_the_server_down_and_each_kind_is_counted(served):
    srv, thread, reports = served
    a, b = _socket(), _socket()
    addr = srv.address
    good = _hello()
    # not the protocol: wrong sizes, magic, version, an unknown kind
    malformed = [b"", b"x", good[:-1], good + b"\0", b"\0" * 300, b"XXXX" + good[4:],
                 good[:4] + bytes([9]) + good[5:], pack(9, 0, 0.0, 0.0, 0.0)]
    for data in malformed:
        a.sendto(data, addr)
    # the protocol, with values no rig can take: positions, start times, sample times, commands
    invalid = [_hello(position=v) for v in (NAN, INF, -INF, -1.0, 1e308, 5.0)]
    invalid += [_hello(t0=v) for v in (NAN, INF, -INF, 1e308, -1e308)]
    invalid += [_hello(sample_time=v) for v in (NAN, INF, -TS, 0.0, 1e308)]
    invalid += [_hello(command=v) for v in (NAN, INF, -1e308, 1e308, -3.0, 99.0)]
    for data in invalid:
        a.sendto(data, addr)
        msg = _reply(a)
        assert msg is not None and msg[0] == READY and msg[1] != 0          # refused, and told so
    assert _wait(lambda: srv.stats.malformed == len(malformed) and srv.stats.invalid == len(invalid))
    assert thread.is_alive() and srv.stats.sessions == 0 and not srv.active and srv.valve_V == 5.0
    # commands and goodbyes without a session
    a.sendto(pack(CMD, 0, 0.0, 0.0, 6.0), addr)
    a.sendto(pack(BYE, 0, 0.0, 0.0, 9.0), addr)
    assert _wait(lambda: srv.stats.stray == 2) and srv.valve_V == 5.0

    # a session: duplicated, reordered, out-of-range and foreign datagrams within it
    a.sendto(good, addr)
    assert _reply(a)[0] == READY and srv.active
    a.sendto(pack(CMD, 0, 0.0, 0.0, 6.0), addr)
    assert _reply(a)[:3] == (MEAS, 0, 1)
    a.sendto(pack(CMD, 0, 0.0, 0.0, 7.0), addr)               # the same command again
    a.sendto(pack(CMD, 2, 0.0, 0.0, 6.0), addr)               # 2 before 1: 1 is held as lost
    assert _reply(a)[:3] == (MEAS, 0, 3)
    a.sendto(pack(CMD, 1, 0.0, 0.0, 6.0), addr)               # 1 turns up late
    for v in (NAN, INF, -INF, 1e308, -2.0, 11.0):             # commands outside the valve's range
        a.sendto(pack(CMD, 3, 0.0, 0.0, v), addr)
    b.sendto(pack(CMD, 3, 0.0, 0.0, 9.5), addr)               # another process's command
    b.sendto(pack(BYE, 3, 0.0, 0.0, 9.5), addr)               # and its goodbye
    b.sendto(_hello(stamp=2.0), addr)                          # a second loop's session
    busy = _reply(b)
    assert busy is not None and busy[0] == READY and busy[1] != 0
    assert _wait(lambda: srv.stats.refused_hellos == 1 and srv.stats.foreign == 2 and srv.stats.late_commands == 1
                 and srv.stats.duplicates == 1 and srv.stats.invalid == len(invalid) + 6)
    assert srv.active and srv.valve_V == 6.0 and srv.stats.lost_commands == 1
    a.sendto(pack(CMD, 3, 0.0, 0.0, 6.5), addr)               # the session goes on
    assert _reply(a)[:3] == (MEAS, 0, 4) and srv.valve_V == 6.5

    # the loop goes silent: the watchdog still drives the valve to its null
    assert _wait(lambda: srv.stats.watchdog_trips == 1, timeout=3.0)
    assert srv.valve_V == 5.0 and not srv.active and thread.is_alive()
    # the session is over: the second loop may start one now
    b.sendto(_hello(stamp=3.0), addr)
    assert _reply(b)[:2] == (READY, 0) and srv.stats.sessions == 2
    b.sendto(pack(BYE, 0, 0.0, 0.0, NAN), addr)
    assert _wait(lambda: not srv.active) and srv.valve_V == 5.0

    # the counts are in the statistics and were reported while the server ran
    text = srv.stats.line(srv.valve_V)
    for words in (f"malformed {len(malformed)}", f"invalid {len(invalid) + 6}", "foreign 2", "refused hellos 1",
                  "duplicates 1", "late commands 1", "lost commands 1", "stray 2", "watchdog trips 1"):
        assert words in text
    assert _wait(lambda: any("malformed 8" in r and "refused hellos 1" in r for r in reports))
    assert any("refused a session from" in e for e in srv.stats.events)
    a.close()
    b.close()


def test_a_bye_never_leaves_the_valve_outside_its_range(served):
    srv, thread, _ = served
    a = _socket()
    for value in (1e308, -50.0, INF):
        a.sendto(_hello(stamp=value), srv.address)
        assert _reply(a)[:2] == (READY, 0)
        a.sendto(pack(BYE, 0, 0.0, 0.0, value), srv.address)
        assert _wait(lambda: not srv.active)
        assert srv.valve_V == 5.0
    assert thread.is_alive()
    a.close()


def test_a_second_loop_is_refused_while_the_first_runs_and_the_first_keeps_its_session(served):
    srv, _, _ = served
    rig = load_rig("paper1-mre")
    first = UdpPlant("127.0.0.1", srv.address[1], rig.sample_time_s, reply_timeout_s=0.5)
    second = UdpPlant("127.0.0.1", srv.address[1], rig.sample_time_s, reply_timeout_s=0.5, connect_timeout_s=1.0)
    first.reset(0.02, 5.0)
    first.measure()
    first.step(6.0)
    with pytest.raises(PneusimError, match="serving another loop"):
        second.reset(0.03, 5.0)
    for _ in range(5):                 # the first loop is answered at once, sample after sample
        first.measure()
        first.step(6.0)
    first.measure()
    assert first.lost == 0 and srv.stats.refused_hellos >= 1 and srv.stats.sessions == 1
    first.safe_stop(5.0)
    first.close()
    second.close()


def test_a_hello_with_a_nan_sample_time_is_refused(served):
    srv, _, _ = served
    a = _socket()
    a.sendto(_hello(sample_time=NAN), srv.address)
    msg = _reply(a)
    assert msg[0] == READY and msg[1] != 0 and srv.stats.sessions == 0 and srv.stats.invalid == 1
    a.close()


def test_serve_rig_survives_the_issues_datagrams_and_prints_its_counts_on_sigterm():
    """``pneusim serve-rig``: a HELLO at position NaN (and inf, -1, 1e308, t0 NaN/inf) then a command used to
    end it with a traceback; it must stay up, and SIGTERM must print the statistics as Ctrl-C does."""
    with serve_rig_process("--report-interval", "0.2", stderr=subprocess.PIPE) as (srv, port):
        a = _socket()
        bad = [struct.pack(FORMAT, b"PNRS", 1, 1, 0, 0, 1.0, 0.001, NAN, 5.0, 0.0)]
        bad += [_hello(position=v) for v in (INF, -1.0, 1e308)] + [_hello(t0=v) for v in (NAN, INF)]
        for data in bad:
            a.sendto(data, ("127.0.0.1", port))
            _reply(a)
            a.sendto(pack(CMD, 0, 0.0, 0.0, 6.0), ("127.0.0.1", port))
        a.sendto(b"junk", ("127.0.0.1", port))
        time.sleep(0.5)
        assert srv.poll() is None, srv.stderr.read()
        srv.send_signal(signal.SIGTERM)
        out, err = srv.communicate(timeout=20)
    assert srv.returncode == 0, err       # a server stopped as asked, as on Ctrl-C
    assert "Traceback" not in err
    assert "invalid 6" in out and "stray 6" in out and "malformed 1" in out and "valve at 5 V" in out
    assert "terminated (SIGTERM)" in err
