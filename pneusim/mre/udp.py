"""A rig in another process over UDP: the protocol, the loop's plant and the rig server.

One datagram per sample in each direction, the way a real-time target or a DAQ
box on the network is used::

    loop (UdpPlant)                         rig server (RigServer, ``pneusim serve-rig``)
    HELLO(position, command, t0)   ---->    reset the rig at time t0, valve at the command
                                   <----    READY seq 0: measurement of sample 0
    CMD seq k, u(k), t_sent        ---->    hold u(k) for one sample, measure sample k+1
                                   <----    MEAS seq k+1, measurement, t_sent echoed
    ...
    BYE(null)                      ---->    valve to null, session over

Every datagram is ``struct`` :data:`FORMAT` (little endian, 60 bytes): magic
``PNRS``, version, type, flags, sequence number, the sender's
``time.perf_counter`` stamp, the stamp echoed from the datagram it answers, and
three values (command V, or position m and chamber pressures Pa).

Nothing is hidden:

* the loop waits for ``MEAS seq k`` at most ``reply_timeout_s``; if it does not
  come the sample is **lost**: the last measurement is held, the sample is
  flagged (``plant_flag = 1``) and counted; a reply that turns up later is
  counted **late** and dropped;
* the server counts commands that never arrived (a gap in the sequence: the
  previous command is held for that sample) and commands that arrived after a
  newer one (late, ignored);
* **watchdog**: if the loop goes silent for longer than ``watchdog_s`` during a
  session, the server drives the valve to its null and holds it there until a
  new session starts.

The server steps its simulated rig when a command arrives: it is paced by the
loop (lock-step), so its simulated time stays exactly aligned with the sequence
numbers, and a paced loop makes it run in real time.
"""

from __future__ import annotations

import select
import socket
import struct
import time
from dataclasses import dataclass, field

from ..errors import PneusimError
from ..plant import Measurement

__all__ = ["UdpPlant", "RigServer", "FORMAT", "HELLO", "READY", "CMD", "MEAS", "BYE", "pack", "unpack"]

MAGIC = b"PNRS"
VERSION = 1
FORMAT = "<4sBBHQddddd"
SIZE = struct.calcsize(FORMAT)
HELLO, READY, CMD, MEAS, BYE = 1, 2, 3, 4, 5
#: flag of a READY datagram: the loop's sample time (sent in HELLO's echo field) is not the rig's
FLAG_SAMPLE_TIME = 1


_STRUCT = struct.Struct(FORMAT)      # compiled once: packing and unpacking run at every sample


def pack(kind: int, seq: int, t_sent: float, t_echo: float, v0: float, v1: float = float("nan"),
         v2: float = float("nan"), flags: int = 0) -> bytes:
    return _STRUCT.pack(MAGIC, VERSION, kind, flags, seq, t_sent, t_echo, v0, v1, v2)


def unpack(data: bytes):
    """``(kind, flags, seq, t_sent, t_echo, v0, v1, v2)`` or ``None`` for a datagram that is not ours."""
    if len(data) != SIZE:
        return None
    magic, version, kind, flags, seq, t_sent, t_echo, v0, v1, v2 = _STRUCT.unpack(data)
    if magic != MAGIC or version != VERSION:
        return None
    return kind, flags, seq, t_sent, t_echo, v0, v1, v2


class UdpPlant:
    """The loop's side: a :class:`~pneusim.plant.Plant` whose rig is a server at ``host:port``.

    Parameters
    ----------
    host, port : str, int
    sample_time_s : float
    reply_timeout_s : float
        How long :meth:`measure` waits for the sample's measurement before holding the last one.
    connect_timeout_s : float
        How long :meth:`reset` waits for the server's READY.
    drop_commands : set of int
        Sequence numbers of commands not sent (fault injection for tests).

    Attributes
    ----------
    lost, late : int
        Measurements that did not arrive in time; replies that arrived after their sample.
    measurement_flag : int
        1 when the last :meth:`measure` held the previous measurement, else 0.
    rtt_s : list of float
        Round-trip time of every measurement received in time, s.
    """

    def __init__(self, host: str, port: int, sample_time_s: float, reply_timeout_s: float = 1.0,
                 connect_timeout_s: float = 2.0, drop_commands=()):
        self.host, self.port = host, int(port)
        self.sample_time_s = float(sample_time_s)
        self.reply_timeout_s = float(reply_timeout_s)
        self.connect_timeout_s = float(connect_timeout_s)
        self.drop_commands = set(drop_commands)
        self.lost = self.late = 0
        self.measurement_flag = 0
        self.rtt_s: list[float] = []
        self.sock: socket.socket | None = None

    @property
    def where(self) -> str:
        return f"udp:{self.host}:{self.port}"

    def _open(self):
        if self.sock is None:
            try:
                addr = socket.getaddrinfo(self.host, self.port, socket.AF_INET, socket.SOCK_DGRAM)[0][4]
            except socket.gaierror as exc:
                raise PneusimError(f"{self.where}: unknown host ({exc.strerror})") from None
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.connect(addr)
            self.sock.setblocking(False)

    def _recv(self, timeout_s: float):
        """Next datagram of ours within ``timeout_s``, or None.

        The reply of a paced loop's sample has usually arrived while the loop waited for its
        deadline: one non-blocking ``recv`` takes it, ``select`` is called only when nothing is there.
        """
        end = None
        while True:
            try:
                data = self.sock.recv(256)
            except ConnectionRefusedError:   # ICMP port unreachable from an earlier send: nobody listens
                raise PneusimError(f"{self.where}: no rig server is listening there "
                                   "(start one with: pneusim serve-rig --rig RIG --port PORT)") from None
            except BlockingIOError:
                now = time.perf_counter()
                if end is None:
                    end = now + timeout_s
                rest = end - now
                if rest < 0:
                    return None
                ready, _, _ = select.select([self.sock], [], [], rest)
                if not ready:
                    return None
                continue
            msg = unpack(data)
            if msg is not None:
                return msg

    def reset(self, position_m: float, command_V: float, t0_s: float = 0.0) -> None:
        """Start a session: the server resets its rig at ``position_m`` with ``command_V`` applied."""
        self._open()
        self._t0, self._k = float(t0_s), 0
        self.lost = self.late = 0
        self.rtt_s = []
        # the loop's sample time travels in the echo field, the start time t0_s in the third value;
        # HELLO is repeated every 0.2 s (a datagram may be lost) until READY or the timeout
        stamp = time.perf_counter()          # the same in every repeat: the server answers a repeat once more
        deadline = stamp + self.connect_timeout_s
        msg = None
        while msg is None or msg[0] != READY:
            rest = deadline - time.perf_counter()
            if rest <= 0:
                raise PneusimError(f"{self.where}: no rig server answered within {self.connect_timeout_s:g} s "
                                   "(start one with: pneusim serve-rig --rig RIG --port PORT)")
            self.sock.send(pack(HELLO, 0, stamp, self.sample_time_s, position_m, command_V, t0_s))
            msg = self._recv(min(0.2, rest))
        if msg[1] & FLAG_SAMPLE_TIME:
            raise PneusimError(f"{self.where}: the rig server's sample time differs from the loop's "
                               f"{self.sample_time_s:g} s; serve the same rig")
        self._last = Measurement(self._t0, msg[5], msg[6], msg[7])
        self._pending = self._last

    def measure(self) -> Measurement:
        t_s = self._t0 + self._k * self.sample_time_s
        if self._k == 0:
            self.measurement_flag = 0
            return self._last
        while True:
            msg = self._recv(self.reply_timeout_s)
            if msg is None:
                self.lost += 1
                self.measurement_flag = 1
                self._last = Measurement(t_s, self._last.position_m, self._last.pressure_a_Pa,
                                         self._last.pressure_b_Pa)
                return self._last
            kind, _flags, seq = msg[0], msg[1], msg[2]
            if kind != MEAS:
                continue
            if seq < self._k:
                self.late += 1
                continue
            self.rtt_s.append(time.perf_counter() - msg[4])
            self.measurement_flag = 0
            self._last = Measurement(t_s, msg[5], msg[6], msg[7])
            return self._last

    def step(self, command_V: float) -> None:
        """Send ``u(k)``; the server holds it for one sample and answers with sample ``k+1``."""
        if self._k not in self.drop_commands:
            self.sock.send(pack(CMD, self._k, time.perf_counter(), 0.0, float(command_V)))
        self._k += 1

    def safe_stop(self, null_V: float | None = None) -> None:
        """End the session: the server drives the valve to ``null_V`` (its rig's null when None)."""
        if self.sock is not None:
            self.sock.send(pack(BYE, self._k, time.perf_counter(), 0.0,
                                float("nan") if null_V is None else float(null_V)))

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
            self.sock = None


@dataclass
class ServerStats:
    """What a :class:`RigServer` counted (all per session except ``sessions`` and ``watchdog_trips``)."""

    sessions: int = 0
    commands: int = 0
    lost_commands: int = 0
    late_commands: int = 0
    stray: int = 0
    watchdog_trips: int = 0
    byes: int = 0
    events: list = field(default_factory=list)


class RigServer:
    """A simulated rig served over UDP (see the module docstring for the protocol).

    Parameters
    ----------
    plant : SimulatedPlant
        The rig; reset by each HELLO.
    host, port : str, int
        Where to listen (port 0: any free port, see :attr:`address`).
    watchdog_s : float
        Silence (no command) during a session after which the valve is driven to null.
    null_V : float
        The valve's null.
    drop_replies : set of int
        Sequence numbers of measurements not sent (fault injection for tests).
    max_gap : int
        Largest gap of lost commands the server fills by holding the last command; a larger
        jump ends the session (valve to null).
    """

    def __init__(self, plant, host: str = "127.0.0.1", port: int = 0, watchdog_s: float = 0.1,
                 null_V: float = 5.0, drop_replies=(), max_gap: int = 1000):
        self.plant = plant
        self.watchdog_s = float(watchdog_s)
        self.null_V = float(null_V)
        self.drop_replies = set(drop_replies)
        self.max_gap = int(max_gap)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, int(port)))
        except OSError as exc:
            self.sock.close()
            raise PneusimError(f"--port {port}: cannot listen on {host}:{port} ({exc.strerror or exc})") from None
        self.address = self.sock.getsockname()
        self.stats = ServerStats()
        self.valve_V = self.null_V
        self.active = False
        self.peer = None
        self._expected = 0
        self._last_rx = 0.0
        self._hello_stamp = None
        self._ready = b""

    def _send(self, kind, seq, t_echo, m: Measurement, flags=0):
        if kind == MEAS and seq in self.drop_replies:
            return
        self.sock.sendto(pack(kind, seq, time.perf_counter(), t_echo, m.position_m, m.pressure_a_Pa,
                              m.pressure_b_Pa, flags), self.peer)

    def _trip(self, why: str):
        self.valve_V = self.null_V
        self.active = False
        self.stats.events.append(why)

    def handle(self, data: bytes, peer) -> None:
        """Process one datagram."""
        msg = unpack(data)
        if msg is None:
            self.stats.stray += 1
            return
        kind, _flags, seq, t_sent, echo, v0, v1, v2 = msg
        now = time.perf_counter()
        if kind == HELLO and self.active and peer == self.peer and t_sent == self._hello_stamp:
            self.sock.sendto(self._ready, peer)     # a repeated HELLO: the same READY again, no second reset
            return
        if kind == HELLO:
            self.peer = peer
            if abs(echo - self.plant.sample_time_s) > 1e-9 * self.plant.sample_time_s:
                self.stats.events.append(f"refused a session from {peer[0]}:{peer[1]}: sample time {echo:g} s")
                self.sock.sendto(pack(READY, 0, time.perf_counter(), t_sent, float("nan"), flags=FLAG_SAMPLE_TIME),
                                 peer)
                return
            self.plant.reset(v0, v1, v2)
            self.valve_V = v1
            self.active, self._expected, self._last_rx = True, 0, now
            self.stats.sessions += 1
            self.stats.events.append(f"session {self.stats.sessions} from {peer[0]}:{peer[1]}")
            m = self.plant.measure()
            self._hello_stamp = t_sent
            self._ready = pack(READY, 0, time.perf_counter(), t_sent, m.position_m, m.pressure_a_Pa, m.pressure_b_Pa)
            self.sock.sendto(self._ready, peer)
            return
        if not self.active or peer != self.peer:
            self.stats.stray += 1
            return
        self._last_rx = now
        if kind == BYE:
            self.stats.byes += 1
            self.valve_V = self.null_V if v0 != v0 else v0
            self.active = False
            self.stats.events.append("session ended by the loop: valve to null")
            return
        if kind != CMD:
            self.stats.stray += 1
            return
        if seq < self._expected:
            self.stats.late_commands += 1
            return
        if seq - self._expected > self.max_gap:
            self._trip(f"sequence jumped from {self._expected} to {seq}: valve to null")
            return
        while self._expected < seq:             # commands that never came: the valve holds the last one
            self.plant.step(self.valve_V)
            self.plant.measure()                # the rig is sampled every period; nobody asked for this one
            self.stats.lost_commands += 1
            self._expected += 1
        self.valve_V = v0
        self.plant.step(v0)
        self.stats.commands += 1
        self._expected = seq + 1
        self._send(MEAS, seq + 1, t_sent, self.plant.measure())

    def check_watchdog(self) -> bool:
        """Drive the valve to null if the session has been silent too long; True when it tripped."""
        if self.active and time.perf_counter() - self._last_rx > self.watchdog_s:
            self.stats.watchdog_trips += 1
            self._trip(f"watchdog: no command for {self.watchdog_s:g} s: valve to null ({self.null_V:g} V)")
            return True
        return False

    def serve(self, stop=None, max_sessions: int | None = None, idle_timeout_s: float | None = None) -> ServerStats:
        """Serve until ``stop`` (a :class:`threading.Event`) is set, ``max_sessions`` sessions have ended,
        or nothing arrived for ``idle_timeout_s`` outside a session."""
        poll = min(self.watchdog_s / 4, 0.05)
        idle_since = time.perf_counter()
        while stop is None or not stop.is_set():
            ready, _, _ = select.select([self.sock], [], [], poll)
            if ready:
                data, peer = self.sock.recvfrom(256)
                self.handle(data, peer)
                idle_since = time.perf_counter()
            self.check_watchdog()
            ended = self.stats.sessions - (1 if self.active else 0)
            if max_sessions is not None and ended >= max_sessions and not self.active:
                break
            if idle_timeout_s is not None and not self.active and time.perf_counter() - idle_since > idle_timeout_s:
                break
        return self.stats

    def close(self) -> None:
        self.sock.close()
