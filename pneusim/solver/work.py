"""The model work a computation has done, counted the same on every machine.

A budget on processor time buys a machine half as fast half the search, and a loaded machine (shared caches, a
second hardware thread) less still, so a diagnosis stopped by its budget gave another answer on another machine
(``docs/decisions/0115``).  Work counted in the model's own terms does not depend on the CPU: one **unit** is one
sample of the model integrated for one column -- the state, or one sensitivity column -- so a sample with ``ns``
sensitivity columns costs ``1 + ns`` units (:class:`~.sensitivity.SensitivitySimulator` charges every sample it
integrates, before integrating it, failed or not).

The count follows the computation's logic, not the threads' timing.  Work is charged to the calling thread's
**ledger** (the process's by default).  A computation run on another thread whose result may be dropped (the
prediction-error starts run side by side and the ones not needed are cancelled half-way) gets a :func:`branch`:
it opens at its parent's count at the moment it is started, charges its own work there, and adds that work to
the ledger of whoever takes its result (:meth:`Ledger.merge`); a branch whose result is never taken adds nothing,
however far it ran.  Threads that split one computation whose parts all finish (the segments of one shooting
evaluation) run on their caller's ledger (:func:`on`).
"""

from __future__ import annotations

import contextlib
import threading

__all__ = ["Ledger", "branch", "charge", "current", "done", "on", "on_branch"]


class Ledger:
    """Units of work charged, on top of ``base`` (a branch's parent's count when it was opened)."""

    def __init__(self, base: int = 0):
        self.base, self.units = int(base), 0
        #: set by :mod:`pneusim.fit.deadline` where a deadline stopped work on this branch
        self.stopped = False
        self._lock = threading.Lock()

    def charge(self, units: int) -> None:
        with self._lock:
            self.units += int(units)

    def total(self) -> int:
        """The count this ledger's work sees: its base and its own units."""
        return self.base + self.units

    def merge(self) -> None:
        """Add this branch's units to the ledger of the calling thread (whoever takes the branch's result)."""
        current().charge(self.units)


_PROCESS = Ledger()
_local = threading.local()


def current() -> Ledger:
    """The calling thread's ledger (the process's unless :func:`on` set another)."""
    return getattr(_local, "ledger", None) or _PROCESS


def on_branch() -> bool:
    """Whether the calling thread works on a :func:`branch` (not the process's ledger)."""
    return current() is not _PROCESS


def charge(units: int) -> None:
    """Charge ``units`` to the calling thread's ledger."""
    current().charge(units)


def done() -> int:
    """Units of work the calling thread's ledger has counted (a branch: its parent's at its opening and its own)."""
    return current().total()


def branch() -> Ledger:
    """A ledger for work on another thread whose result may not be taken: opened at the calling thread's count;
    run the work :func:`on` it and :meth:`~Ledger.merge` it where the result is taken."""
    return Ledger(base=done())


@contextlib.contextmanager
def on(ledger: Ledger):
    """Within the block, the calling thread's work is charged to ``ledger``."""
    previous = getattr(_local, "ledger", None)
    _local.ledger = ledger
    try:
        yield ledger
    finally:
        _local.ledger = previous
