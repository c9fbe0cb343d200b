"""A rig in another process over UDP: the protocol and the loop's plant (the server: :mod:`.rig_server`).

One datagram per sample in each direction, the way a real-time target or a DAQ
box on the network is used::

    loop (UdpPlant)                         rig server (rig_server.RigServer, ``pneusim serve-rig``)
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
  new session starts;
* a HELLO the server refuses is answered by a READY whose flags say why
  (:data:`FLAG_SAMPLE_TIME`, :data:`FLAG_BUSY`, :data:`FLAG_REFUSED`), and
  :meth:`UdpPlant.reset` says so in one line.  What the server checks and
  counts: :mod:`pneusim.mre.rig_server`.

The server steps its simulated rig when a command arrives: it is paced by the
loop (lock-step), so its simulated time stays exactly aligned with the sequence
numbers, and a paced loop makes it run in real time.
"""

from __future__ import annotations

import select
import socket
import struct
import time

from ..errors import PneusimError
from ..plant import Measurement

__all__ = ["UdpPlant", "FORMAT", "HELLO", "READY", "CMD", "MEAS", "BYE", "FLAG_SAMPLE_TIME", "FLAG_BUSY",
           "FLAG_REFUSED", "pack", "unpack"]

MAGIC = b"PNRS"
VERSION = 1
FORMAT = "<4sBBHQddddd"
SIZE = struct.calcsize(FORMAT)
HELLO, READY, CMD, MEAS, BYE = 1, 2, 3, 4, 5
#: flags of a READY datagram that refuses a session: the loop's sample time (sent in HELLO's echo field) is
#: not the rig's; the server is serving another loop; the HELLO's values are outside what the rig can take
FLAG_SAMPLE_TIME = 1
FLAG_BUSY = 2
FLAG_REFUSED = 4


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
        if msg[1] & FLAG_BUSY:
            raise PneusimError(f"{self.where}: the rig server is serving another loop; wait until its session "
                               "ends, or start another server (pneusim serve-rig --port ANOTHER)")
        if msg[1]:
            raise PneusimError(f"{self.where}: the rig server refused the session: position {position_m!r} m, "
                               f"command {command_V!r} V or start time {t0_s!r} s is outside what its rig can take")
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
