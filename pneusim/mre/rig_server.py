"""The rig server (``pneusim serve-rig``): a simulated rig served over UDP to one loop at a time.

The protocol is :mod:`pneusim.mre.udp`'s.  On a real rig the server's watchdog is the safety function
that holds the valve at its null when the loop goes silent, so no datagram -- from the loop or from any
other process that can reach the port -- may take the server down or drive the valve where the rig
cannot go:

* every datagram is checked before it touches the rig.  Not the protocol (size, magic, version, kind):
  counted **malformed**.  The protocol with values no rig can take -- a position outside the stroke, a
  command outside the valve's range, a sample time other than the rig's, a start time beyond
  :data:`~pneusim.experiment.MAX_SAMPLES` samples, anything not finite: counted **invalid** and
  refused (a HELLO gets a READY whose flags say why; a command is dropped, so its sample is lost);
* one session at a time: a HELLO from another address while a session is live is refused (a READY
  with :data:`~pneusim.mre.udp.FLAG_BUSY`), counted (**refused hellos**) and reported, until the
  session ends (BYE, the watchdog, a sequence jump); the first loop keeps its session;
* a command applied once more is a **duplicate**; one that arrives after a newer one is **late** (its
  sample was held as lost); datagrams of another address during a session are **foreign**, commands and
  goodbyes without a session **stray**; all dropped and counted;
* anything that goes wrong while a datagram is handled (a solver failure, a send refused by the
  network) ends the session with the valve at its null and is counted as an **error**; the server
  stays up;
* **watchdog**: a session silent for longer than ``watchdog_s`` drives the valve to its null and holds
  it there until a new session starts.

The counts are in :attr:`RigServer.stats` (:meth:`ServerStats.line`), reported while the server runs
(``serve(report=...)``, every ``report_interval_s`` when they changed) and at its end.
"""

from __future__ import annotations

import math
import select
import socket
import time
from collections import deque
from dataclasses import asdict, dataclass, field

from ..errors import PneusimError
from ..experiment import MAX_SAMPLES
from ..plant import Measurement
from .udp import BYE, CMD, FLAG_BUSY, FLAG_REFUSED, FLAG_SAMPLE_TIME, HELLO, MEAS, READY, pack, unpack

__all__ = ["RigServer", "ServerStats", "COUNTS"]

#: the counters of :class:`ServerStats`, in the order :meth:`ServerStats.line` reports them
COUNTS = ("sessions", "commands", "lost_commands", "late_commands", "duplicates", "malformed", "invalid", "foreign",
          "refused_hellos", "stray", "errors", "watchdog_trips", "byes")
#: events kept for the report (the oldest are dropped beyond this: a flood cannot fill the memory)
MAX_EVENTS = 1000


@dataclass
class ServerStats:
    """What a :class:`RigServer` counted over its life (see the module docstring for each kind)."""

    sessions: int = 0
    commands: int = 0
    lost_commands: int = 0
    late_commands: int = 0
    duplicates: int = 0
    malformed: int = 0
    invalid: int = 0
    foreign: int = 0
    refused_hellos: int = 0
    stray: int = 0
    errors: int = 0
    watchdog_trips: int = 0
    byes: int = 0
    events: deque = field(default_factory=lambda: deque(maxlen=MAX_EVENTS))
    n_events: int = 0

    def event(self, text: str) -> None:
        """Keep an event for the report (the last :data:`MAX_EVENTS`; :attr:`n_events` counts them all)."""
        self.events.append(text)
        self.n_events += 1

    def counts(self) -> dict:
        return {k: v for k, v in asdict(self).items() if k in COUNTS}

    def line(self, valve_V: float | None = None) -> str:
        """``sessions 1, commands 199, lost commands 0, ...[, valve at 5 V]``: every count, one line."""
        text = ", ".join(f"{k.replace('_', ' ')} {getattr(self, k)}" for k in COUNTS)
        return text + ("" if valve_V is None else f", valve at {valve_V:g} V")


def _finite_in(value: float, low: float, high: float) -> bool:
    return math.isfinite(value) and low <= value <= high


class RigServer:
    """A simulated rig served over UDP (see the module docstring, and :mod:`pneusim.mre.udp` for the protocol).

    Parameters
    ----------
    plant : SimulatedPlant
        The rig; reset by each HELLO.  Its rig's stroke and valve range bound what a datagram may ask.
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
        rig = getattr(plant, "rig", None)
        inf = float("inf")
        self.stroke_m = float(rig.stroke_m) if rig is not None else inf
        self.valve_range_V = ((float(rig.params["valve_min_V"]), float(rig.params["valve_max_V"]))
                              if rig is not None else (-inf, inf))
        self.max_abs_t0_s = MAX_SAMPLES * plant.sample_time_s
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
        self._filled: set[int] = set()        # commands of this session held as lost (a late one may turn up)
        self._last_rx = 0.0
        self._hello_stamp = None
        self._ready = b""
        self._busy_from: set = set()          # addresses refused while this session runs (one event each)
        self._events_reported = 0

    # ------------------------------------------------------------ sending
    def _sendto(self, data: bytes, peer) -> None:
        try:
            self.sock.sendto(data, peer)
        except OSError as exc:             # the network refused it: counted, the server goes on
            self.stats.errors += 1
            self.stats.event(f"could not answer {peer[0]}:{peer[1]} ({exc.strerror or exc})")

    def _send(self, kind, seq, t_echo, m: Measurement, flags=0):
        if kind == MEAS and seq in self.drop_replies:
            return
        self._sendto(pack(kind, seq, time.perf_counter(), t_echo, m.position_m, m.pressure_a_Pa, m.pressure_b_Pa,
                          flags), self.peer)

    def _refuse(self, peer, t_sent: float, flags: int) -> None:
        self._sendto(pack(READY, 0, time.perf_counter(), t_sent, float("nan"), flags=flags), peer)

    def _trip(self, why: str):
        self.valve_V = self.null_V
        self.active = False
        self.stats.event(why)

    # ------------------------------------------------------------ datagrams
    def handle(self, data: bytes, peer) -> None:
        """Process one datagram (see the module docstring for what is refused and counted)."""
        msg = unpack(data)
        if msg is None or msg[0] not in (HELLO, CMD, BYE):
            self.stats.malformed += 1
            return
        kind, _flags, seq, t_sent, echo, v0, v1, v2 = msg
        if kind == HELLO:
            self._hello(peer, t_sent, echo, v0, v1, v2)
        elif not self.active:
            self.stats.stray += 1
        elif peer != self.peer:
            self.stats.foreign += 1
        elif kind == BYE:
            self._bye(v0)
        else:
            self._command(seq, t_sent, v0)

    def _hello(self, peer, t_sent, sample_time_s, position_m, command_V, t0_s) -> None:
        if self.active and peer == self.peer and t_sent == self._hello_stamp:
            self._sendto(self._ready, peer)      # a repeated HELLO: the same READY again, no second reset
            return
        if self.active and peer != self.peer:
            self.stats.refused_hellos += 1
            if peer not in self._busy_from:
                self._busy_from.add(peer)
                self.stats.event(f"refused a session from {peer[0]}:{peer[1]}: the session from "
                                         f"{self.peer[0]}:{self.peer[1]} is live")
            self._refuse(peer, t_sent, FLAG_BUSY)
            return
        ts = self.plant.sample_time_s
        if not (math.isfinite(sample_time_s) and abs(sample_time_s - ts) <= 1e-9 * ts):
            self._invalid_hello(peer, t_sent, FLAG_SAMPLE_TIME, f"sample time {sample_time_s!r} s (the rig's: {ts:g} s)")
            return
        lo, hi = self.valve_range_V
        why = None
        if not _finite_in(position_m, 0.0, self.stroke_m):
            why = f"position {position_m!r} m (the stroke: 0 .. {self.stroke_m:g} m)"
        elif not _finite_in(command_V, lo, hi):
            why = f"command {command_V!r} V (the valve's range: {lo:g} .. {hi:g} V)"
        elif not _finite_in(t0_s, -self.max_abs_t0_s, self.max_abs_t0_s):
            why = f"start time {t0_s!r} s (at most {MAX_SAMPLES} samples from 0)"
        if why:
            self._invalid_hello(peer, t_sent, FLAG_REFUSED, why)
            return
        self.plant.reset(position_m, command_V, t0_s)
        self.peer = peer
        self.valve_V = command_V
        self.active, self._expected, self._last_rx = True, 0, time.perf_counter()
        self._filled, self._busy_from = set(), set()
        self.stats.sessions += 1
        self.stats.event(f"session {self.stats.sessions} from {peer[0]}:{peer[1]}")
        m = self.plant.measure()
        self._hello_stamp = t_sent
        self._ready = pack(READY, 0, time.perf_counter(), t_sent, m.position_m, m.pressure_a_Pa, m.pressure_b_Pa)
        self._sendto(self._ready, peer)

    def _invalid_hello(self, peer, t_sent, flags: int, why: str) -> None:
        self.stats.invalid += 1
        self.stats.event(f"refused a session from {peer[0]}:{peer[1]}: {why}")
        self._refuse(peer, t_sent, flags)

    def _bye(self, null_V: float) -> None:
        self._last_rx = time.perf_counter()
        self.stats.byes += 1
        lo, hi = self.valve_range_V
        if not (null_V != null_V or _finite_in(null_V, lo, hi)):      # NaN: the rig's null
            self.stats.invalid += 1
        self.valve_V = null_V if _finite_in(null_V, lo, hi) else self.null_V
        self.active = False
        self.stats.event("session ended by the loop: valve to null")

    def _command(self, seq: int, t_sent: float, command_V: float) -> None:
        lo, hi = self.valve_range_V
        if not _finite_in(command_V, lo, hi):
            self.stats.invalid += 1            # dropped: the sample is lost, the valve holds the last command
            return
        self._last_rx = time.perf_counter()
        if seq < self._expected:
            if seq in self._filled:
                self._filled.discard(seq)
                self.stats.late_commands += 1
            else:
                self.stats.duplicates += 1
            return
        if seq - self._expected > self.max_gap:
            self._trip(f"sequence jumped from {self._expected} to {seq}: valve to null")
            return
        while self._expected < seq:             # commands that never came: the valve holds the last one
            self.plant.step(self.valve_V)
            self.plant.measure()                # the rig is sampled every period; nobody asked for this one
            self.stats.lost_commands += 1
            self._filled.add(self._expected)
            self._expected += 1
        if len(self._filled) > 4 * self.max_gap:
            self._filled = {k for k in self._filled if k >= self._expected - self.max_gap}
        self.valve_V = command_V
        self.plant.step(command_V)
        self.stats.commands += 1
        self._expected = seq + 1
        self._send(MEAS, seq + 1, t_sent, self.plant.measure())

    # ------------------------------------------------------------ serving
    def check_watchdog(self) -> bool:
        """Drive the valve to null if the session has been silent too long; True when it tripped."""
        if self.active and time.perf_counter() - self._last_rx > self.watchdog_s:
            self.stats.watchdog_trips += 1
            self._trip(f"watchdog: no command for {self.watchdog_s:g} s: valve to null ({self.null_V:g} V)")
            return True
        return False

    def _receive(self) -> None:
        """Take one datagram and handle it; whatever goes wrong ends the session safely and is counted."""
        try:
            data, peer = self.sock.recvfrom(256)
        except OSError as exc:
            self.stats.errors += 1
            self.stats.event(f"receive failed ({exc.strerror or exc})")
            return
        try:
            self.handle(data, peer)
        except Exception as exc:  # noqa: BLE001 - the safety function stays up; the error is counted and reported
            self.stats.errors += 1
            self._trip(f"error handling a datagram from {peer[0]}:{peer[1]} ({type(exc).__name__}: {exc}): "
                       "valve to null")

    def serve(self, stop=None, max_sessions: int | None = None, idle_timeout_s: float | None = None,
              report=None, report_interval_s: float = 10.0) -> ServerStats:
        """Serve until ``stop`` (a :class:`threading.Event`) is set, ``max_sessions`` sessions have ended,
        or nothing arrived for ``idle_timeout_s`` outside a session.

        ``report`` (a callable taking one line of text), when given, receives every new event as it happens
        and the counts (:meth:`ServerStats.line`) every ``report_interval_s`` when they changed.
        """
        poll = min(self.watchdog_s / 4, 0.05)
        idle_since = last_report = time.perf_counter()
        reported_counts = self.stats.counts()
        while stop is None or not stop.is_set():
            ready, _, _ = select.select([self.sock], [], [], poll)
            if ready:
                self._receive()
                idle_since = time.perf_counter()
            self.check_watchdog()
            if report is not None:
                self.report_new_events(report)
                now = time.perf_counter()
                if now - last_report >= report_interval_s:
                    last_report = now
                    counts = self.stats.counts()
                    if counts != reported_counts:
                        reported_counts = counts
                        report(self.stats.line(self.valve_V))
            ended = self.stats.sessions - (1 if self.active else 0)
            if max_sessions is not None and ended >= max_sessions and not self.active:
                break
            if idle_timeout_s is not None and not self.active and time.perf_counter() - idle_since > idle_timeout_s:
                break
        return self.stats

    def report_new_events(self, report) -> None:
        """``report(event)`` for each event not reported yet (the last :data:`MAX_EVENTS` of them)."""
        new = min(self.stats.n_events - self._events_reported, len(self.stats.events))
        for event in list(self.stats.events)[len(self.stats.events) - new:]:
            report(event)
        self._events_reported = self.stats.n_events

    def stop_session(self, why: str) -> None:
        """End a live session with the valve at its null (the server is stopping)."""
        if self.active:
            self._trip(f"{why}: valve to null ({self.null_V:g} V)")
        self.valve_V = self.null_V

    def close(self) -> None:
        self.sock.close()
