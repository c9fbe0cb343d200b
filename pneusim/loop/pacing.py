"""Pacing of the sample loop: when sample ``k`` may start.

Every pacer keeps absolute deadlines ``t_start + k * sample_time_s`` on
:func:`time.perf_counter` (a monotonic clock), so waiting never accumulates
drift: a late sample does not push the later deadlines back.

* :class:`FastPacing` does not wait at all (the loop runs as fast as it can,
  today's offline behaviour); its deadlines are still reported so that the same
  loop code runs in both modes.
* :class:`RealtimePacing` sleeps coarsely until ``spin_s`` before the deadline
  and busy-waits the rest (``time.sleep`` alone wakes up 50-100 us late, more on
  a loaded machine).
* :class:`SleepPacing` is the plain ``time.sleep(deadline - now)`` pacing, kept
  as the reference the real-time pacing is benchmarked against.

The waiting pacers first spend spare time on :attr:`Pacing.idle` (the loop sets it to the
recording writer's formatting), when more than ``idle_margin_s`` is left before the deadline.

The clock and the sleep are parameters (``time.perf_counter`` and ``time.sleep`` by default), so
that a test can drive a pacer with a simulated clock.
"""

from __future__ import annotations

import time
from typing import Callable

from ..errors import PneusimError

__all__ = ["Pacing", "FastPacing", "RealtimePacing", "SleepPacing", "make_pacing", "PACING_MODES"]

PACING_MODES = ("fast", "realtime", "sleep")


class Pacing:
    """Base pacer: ``start()`` once, then ``wait(k)`` before sample ``k`` (k = 0, 1, ...)."""

    realtime = False
    name = "fast"

    #: spare time in s before a deadline below which :attr:`idle` is not called
    idle_margin_s = 3e-4

    def __init__(self, sample_time_s: float, *, clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep):
        self.sample_time_s = float(sample_time_s)
        self.clock, self.sleep = clock, sleep
        self.t_start = 0.0
        #: work for the spare time of a paced loop (a callable, short: ~10 us), e.g. formatting the
        #: recording's rows; called by the waiting pacers when more than ``idle_margin_s`` is left
        self.idle = None

    def start(self) -> float:
        """Set the clock's origin (deadline of sample 0) to now; returns it (perf_counter seconds)."""
        self.t_start = self.clock()
        return self.t_start

    def deadline(self, k: int) -> float:
        """Absolute deadline of sample ``k`` in perf_counter seconds."""
        return self.t_start + k * self.sample_time_s

    def wait(self, k: int) -> float:
        """Return once sample ``k`` may start; returns its deadline."""
        return self.deadline(k)


class FastPacing(Pacing):
    """No waiting: as fast as possible."""


class RealtimePacing(Pacing):
    """Coarse ``time.sleep`` until ``spin_s`` before the deadline, then busy-wait.

    Parameters
    ----------
    sample_time_s : float
    spin_s : float
        Busy-wait margin before each deadline, s (0.2 ms by default).
    """

    realtime = True
    name = "realtime"

    def __init__(self, sample_time_s: float, spin_s: float = 2e-4, **timers):
        super().__init__(sample_time_s, **timers)
        self.spin_s = float(spin_s)

    def wait(self, k: int) -> float:
        deadline = self.t_start + k * self.sample_time_s
        clock = self.clock
        if self.idle is not None and deadline - clock() > self.idle_margin_s:
            self.idle()
        rest = deadline - clock() - self.spin_s
        if rest > 0:
            self.sleep(rest)
        while clock() < deadline:
            pass
        return deadline


class SleepPacing(Pacing):
    """``time.sleep`` until the absolute deadline, nothing else (the reference pacing)."""

    realtime = True
    name = "sleep"

    def wait(self, k: int) -> float:
        deadline = self.t_start + k * self.sample_time_s
        if self.idle is not None and deadline - self.clock() > self.idle_margin_s:
            self.idle()
        rest = deadline - self.clock()
        if rest > 0:
            self.sleep(rest)
        return deadline


def make_pacing(mode: str, sample_time_s: float, **timers) -> Pacing:
    """``fast``, ``realtime`` or ``sleep`` (see the module docstring); ``clock`` and ``sleep`` keywords
    replace ``time.perf_counter`` and ``time.sleep``."""
    try:
        kind = {"fast": FastPacing, "realtime": RealtimePacing, "sleep": SleepPacing}[mode]
    except KeyError:
        raise PneusimError(f"unknown pacing {mode!r}; expected one of {', '.join(PACING_MODES)}") from None
    return kind(sample_time_s, **timers)
