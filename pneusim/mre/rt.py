"""Real-time process settings for the paced loop and the rig server (Linux), each with an honest fallback.

What a real-time Linux loop does so that the scheduler, not only the clock, keeps its deadlines:

* **SCHED_FIFO** (``priority`` 1..99): the thread runs before every normal (CFS) task as soon as
  its sleep ends, instead of waiting for its turn behind a CPU-heavy neighbour.  The kernel's
  real-time throttling (``/proc/sys/kernel/sched_rt_runtime_us``, 95 % by default) still
  leaves the machine usable if the loop ever spun without sleeping.
* **CPU affinity** (``cpu``): pin the thread to one CPU (no migration between samples).
* **Locked memory** (``mlockall``, off by default): no page fault pauses the loop.  It makes the
  whole address space resident (for pneusim ~350 MB instead of ~120 MB, 0.2 s to lock), and a
  machine without swap only has the minor faults of first touches, so it is an option.
* **Timer slack** of 1 ns (``prctl(PR_SET_TIMERSLACK)``): sleeps of a normal-priority thread end
  when asked rather than up to 50 us later (a SCHED_FIFO thread has no slack anyway).

Each setting is tried on its own; one that the system refuses (no privilege, no such CPU, not
Linux) leaves the process as it was and adds a one-line notice to :attr:`RealtimeScope.notices`
(printed on stderr by the commands).  Everything is restored when the scope ends.  Garbage
collection is handled by the loop itself (collected, then disabled while it runs).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from dataclasses import dataclass

__all__ = ["RealtimeSettings", "RealtimeScope", "DEFAULT_PRIORITY"]

#: SCHED_FIFO priority used by default: below the 50 of threaded interrupt handlers (where a kernel
#: has them), so that network and timer interrupts still run before the loop.
DEFAULT_PRIORITY = 40
_PR_SET_TIMERSLACK, _PR_GET_TIMERSLACK = 29, 30
_MCL_CURRENT, _MCL_FUTURE = 1, 2


@dataclass(frozen=True)
class RealtimeSettings:
    """What to ask of the operating system while a paced loop runs.

    Parameters
    ----------
    priority : int
        SCHED_FIFO priority 1..99; 0 leaves the scheduling policy alone.
    cpu : int or None
        Pin the thread to this CPU; None leaves the affinity alone.
    lock_memory : bool
        ``mlockall(MCL_CURRENT | MCL_FUTURE)`` while the loop runs (off by default, see above).
    timer_slack : bool
        Timer slack of 1 ns while the loop runs.
    """

    priority: int = DEFAULT_PRIORITY
    cpu: int | None = None
    lock_memory: bool = False
    timer_slack: bool = True

    @classmethod
    def off(cls) -> "RealtimeSettings":
        """Nothing changed (normal scheduling)."""
        return cls(priority=0, cpu=None, lock_memory=False, timer_slack=False)


def _libc():
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
    except OSError:
        return None


def _errno_text() -> str:
    err = ctypes.get_errno()
    return os.strerror(err) if err else "refused"


class RealtimeScope:
    """Context manager applying :class:`RealtimeSettings` to the calling thread (process for memory).

    Parameters
    ----------
    settings : RealtimeSettings or None
        None: nothing changed.
    label : str
        First word of the notices.
    system : module
        Where the scheduling calls come from (``os``; a test passes one that refuses).

    Attributes
    ----------
    applied : list of str
        What took effect, e.g. ``['SCHED_FIFO 40', 'CPU 1', 'timer slack 1 ns']``.
    notices : list of str
        One line per setting the system refused (and what the run does instead).
    """

    def __init__(self, settings: RealtimeSettings | None, label: str = "mre", system=os):
        self.settings = settings or RealtimeSettings.off()
        self.label = label
        self.system = system
        self.applied: list[str] = []
        self.notices: list[str] = []
        self._undo: list = []

    def _notice(self, what: str, why: str, instead: str) -> None:
        self.notices.append(f"{self.label}: {what} not available ({why}); {instead}")

    def __enter__(self) -> "RealtimeScope":
        s = self.settings
        if s.priority:
            self._fifo(int(s.priority))
        if s.cpu is not None:
            self._pin(int(s.cpu))
        libc = _libc() if (s.lock_memory or s.timer_slack) else None
        if s.lock_memory:
            self._lock(libc)
        if s.timer_slack:
            self._slack(libc)
        return self

    def _fifo(self, priority: int) -> None:
        system = self.system
        if not hasattr(system, "sched_setscheduler"):
            self._notice("SCHED_FIFO", "not Linux", "normal scheduling")
            return
        try:
            old_policy, old_param = system.sched_getscheduler(0), system.sched_getparam(0)
            system.sched_setscheduler(0, system.SCHED_FIFO, system.sched_param(priority))
        except (OSError, ValueError) as exc:
            self._notice(f"SCHED_FIFO priority {priority}", getattr(exc, "strerror", None) or str(exc),
                         "normal scheduling: expect more lateness under load")
            return
        self.applied.append(f"SCHED_FIFO {priority}")
        self._undo.append(lambda: system.sched_setscheduler(0, old_policy, old_param))

    def _pin(self, cpu: int) -> None:
        system = self.system
        if not hasattr(system, "sched_setaffinity"):
            self._notice(f"pinning to CPU {cpu}", "not Linux", "the thread may migrate")
            return
        try:
            old = system.sched_getaffinity(0)
            system.sched_setaffinity(0, {cpu})
        except (OSError, ValueError) as exc:
            self._notice(f"pinning to CPU {cpu}", getattr(exc, "strerror", None) or str(exc),
                         "the thread may migrate")
            return
        self.applied.append(f"CPU {cpu}")
        self._undo.append(lambda: system.sched_setaffinity(0, old))

    def _lock(self, libc) -> None:
        if libc is None or not hasattr(libc, "mlockall"):
            self._notice("mlockall", "no C library", "memory may be paged")
            return
        if libc.mlockall(_MCL_CURRENT | _MCL_FUTURE) != 0:
            self._notice("mlockall", _errno_text(), "memory may be paged")
            return
        self.applied.append("memory locked")
        self._undo.append(libc.munlockall)

    def _slack(self, libc) -> None:
        if libc is None or not hasattr(libc, "prctl"):
            self._notice("timer slack 1 ns", "no prctl", "sleeps may end up to 50 us late")
            return
        old = libc.prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0)
        if old < 0 or libc.prctl(_PR_SET_TIMERSLACK, 1, 0, 0, 0) != 0:
            self._notice("timer slack 1 ns", _errno_text(), "sleeps may end up to 50 us late")
            return
        self.applied.append("timer slack 1 ns")
        self._undo.append(lambda: libc.prctl(_PR_SET_TIMERSLACK, old, 0, 0, 0))

    def __exit__(self, *exc) -> None:
        while self._undo:
            undo = self._undo.pop()
            try:
                undo()
            except OSError:       # restoring is best effort; the run's result is already taken
                pass

    def describe(self) -> str:
        """``'SCHED_FIFO 40, memory locked, ...'`` or ``'normal scheduling'``."""
        return ", ".join(self.applied) or "normal scheduling"
