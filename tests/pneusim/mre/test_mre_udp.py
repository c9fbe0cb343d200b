"""The rig server over UDP (127.0.0.1 only): exact agreement with the local loop, recovery from lost
datagrams (counted), and the watchdog."""

import time

import numpy as np
import pytest

from pneusim.loop import run_loop
from pneusim.mre.udp import CMD, UdpPlant, pack
from pneusim.plant import Measurement, SimulatedPlant
from pneusim.rig import load_rig
from pneusim.controller import ProportionalController

from mre_cases import mre_text, rig_server_thread, serve_rig_process

N = 160
MRE_TEXT = mre_text(duration_s=0.2, seed=2)


@pytest.fixture
def server():
    with rig_server_thread(seed=5, watchdog_s=0.05) as (srv, _):
        yield srv


class _Faulty:
    """The local simulator with the same faults the network injects: a held measurement where a reply
    was lost, the previous command held where a command was lost."""

    def __init__(self, plant, hold, stale):
        self.plant, self.hold, self.stale = plant, set(hold), set(stale)
        self.sample_time_s = plant.sample_time_s
        self.k, self.prev_u, self.last = 0, None, None
        self.measurement_flag = 0

    def reset(self, x0, u0, t0_s=0.0):
        self.plant.reset(x0, u0, t0_s)
        self.prev_u = u0

    def measure(self):
        m = self.plant.measure()
        self.measurement_flag = int(self.k in self.hold)
        if self.measurement_flag:
            m = Measurement(m.t_s, self.last.position_m, self.last.pressure_a_Pa, self.last.pressure_b_Pa)
        self.last = m
        return m

    def step(self, u):
        applied = self.prev_u if self.k in self.stale else u
        self.plant.step(applied)
        self.prev_u = applied
        self.k += 1


def _run(plant):
    rig = load_rig("paper1-mre")
    ref = np.where(np.arange(N) < 60, 0.02, 0.05)
    plant.reset(0.02, 5.0, 0.0)
    return run_loop(plant, ref, ProportionalController(40.0), {}, lambda p: p, lambda u, k: u,
                    null_V=rig.params["valve_null_V"])


def test_udp_loop_recovers_from_lost_datagrams_and_counts_them(server):
    rig = load_rig("paper1-mre")
    server.watchdog_s = 5.0                            # longer than the loop's wait for a lost reply
    server.drop_replies = {50}                         # the measurement of sample 50 never arrives
    client = UdpPlant("127.0.0.1", server.address[1], rig.sample_time_s, reply_timeout_s=0.3,
                      drop_commands={100})             # nor does the command of sample 100
    res = _run(client)
    assert res.completed and res.n_samples == N
    # the reply of 50 and the reply to the missing command 100 (sample 101) were lost, not hidden
    assert client.lost == 2 and client.late == 0
    assert np.flatnonzero(res.plant_flag).tolist() == [50, 101]
    assert server.stats.lost_commands == 1 and server.stats.commands == N - 2
    # after each loss the loop carried on in step with the rig: the local simulator with the same
    # faults gives the same samples to the last bit
    local = _run(_Faulty(SimulatedPlant(rig, seed=5), hold={50, 101}, stale={100}))
    np.testing.assert_array_equal(res.position_m, local.position_m)
    np.testing.assert_array_equal(res.valve_cmd_V, local.valve_cmd_V)
    np.testing.assert_array_equal(res.plant_flag, local.plant_flag)
    client.close()


def test_watchdog_drives_the_valve_to_null_when_the_loop_goes_silent(server):
    rig = load_rig("paper1-mre")
    client = UdpPlant("127.0.0.1", server.address[1], rig.sample_time_s, reply_timeout_s=0.3)
    client.reset(0.02, 5.0)
    for _ in range(20):
        client.measure()
        client.step(8.0)                               # valve well open
    client.measure()
    assert server.valve_V == 8.0 and server.active
    end = time.monotonic() + 3.0                       # the loop stops talking
    while server.stats.watchdog_trips == 0 and time.monotonic() < end:
        time.sleep(0.01)
    assert server.stats.watchdog_trips == 1
    assert server.valve_V == 5.0 and not server.active
    # a command that turns up after the trip does not open the valve again
    client.sock.send(pack(CMD, 21, time.perf_counter(), 0.0, 9.0))
    time.sleep(0.2)
    assert server.valve_V == 5.0 and server.stats.stray >= 1
    client.close()


def test_serve_rig_command_line_session_over_udp(tmp_path):
    """``pneusim serve-rig`` in another process and ``pneusim mre --plant udp:...`` give the local run."""
    with serve_rig_process("--seed", "2", "--sessions", "1") as (srv, port):
        mre = tmp_path / "m.toml"
        mre.write_text(MRE_TEXT, encoding="utf-8")
        from pneusim.cli import main
        assert main(["mre", str(mre), "--plant", f"udp:127.0.0.1:{port}", "--fast", "--out", str(tmp_path / "u"),
                     "--no-report"]) == 0
        assert main(["mre", str(mre), "--fast", "--out", str(tmp_path / "s"), "--no-report"]) == 0
        out, _ = srv.communicate(timeout=20)
    assert "commands 199, lost commands 0" in out and "session ended by the loop: valve to null" in out
    from pneusim.recording import read_recording
    u, loc = read_recording(tmp_path / "u" / "recording.csv"), read_recording(tmp_path / "s" / "recording.csv")
    np.testing.assert_array_equal(u.position_m, loc.position_m)
    np.testing.assert_array_equal(u.pressure_a_Pa, loc.pressure_a_Pa)


def test_a_repeated_hello_gets_the_same_ready_without_a_second_reset(server):
    import socket as so

    from pneusim.mre.udp import HELLO, READY, unpack

    s = so.socket(so.AF_INET, so.SOCK_DGRAM)
    s.settimeout(2.0)
    hello = pack(HELLO, 0, 123.456, 0.001, 0.02, 5.0, 0.0)
    s.sendto(hello, server.address)
    first = s.recv(256)
    s.sendto(hello, server.address)                    # as if the READY had been lost
    second = s.recv(256)
    assert first == second and unpack(first)[0] == READY
    assert server.stats.sessions == 1
    s.close()
