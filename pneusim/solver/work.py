"""The model work a computation has done, counted the same on every machine.

A budget on processor time buys a machine half as fast half the search, and a loaded machine (shared caches, a
second hardware thread) less still, so a diagnosis stopped by its budget gave another answer on another machine
(``docs/decisions/0115``).  Work counted in the integrator's own terms does not depend on the CPU's speed or
load: :class:`~.sensitivity.SensitivitySimulator` charges every CVODES step it takes, failed integrations
included, :func:`step_units` units a step -- the step's fixed share (:data:`STEP_UNITS`: the Newton matrix's
setup, the error test) and one unit for each state of each column integrated (the state, or one sensitivity
column).  The steps a run takes follow from its inputs alone, so the count is the same under any load and on
any CPU running the same arithmetic; where a stiff point tried takes thousands of steps a sample, the count
grows with them.

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

__all__ = ["STEP_UNITS", "Ledger", "branch", "charge", "charge_steps", "current", "done", "on", "on_branch",
           "step_units"]

#: (units) a CVODES step's cost beside its states and columns, in the units of one state of one column: one
#: step costs 0.6 us integrating the 4 states alone and 1.5 us with 12 columns (0.0205 us a state-column, 0.52 us
#: fixed), and 2.35 us for 5 states with 16 columns (2.16 us as counted), on the reference machine
STEP_UNITS = 25


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


def step_units(n_states: int, columns: int) -> int:
    """Units one CVODES step of ``n_states`` states with ``columns`` columns (1 + sensitivity columns) costs."""
    return STEP_UNITS + n_states * columns


def charge(units: int) -> None:
    """Charge ``units`` to the calling thread's ledger."""
    current().charge(units)


def charge_steps(steps: int, n_states: int, columns: int) -> None:
    """Charge ``steps`` CVODES steps of ``n_states`` states with ``columns`` columns to the calling thread's
    ledger."""
    current().charge(steps * step_units(n_states, columns))


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
