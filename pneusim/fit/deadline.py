"""A work deadline for fits: a caller that must not run past a point (the diagnosis's time budget) sets one, and
every evaluation of a fit's problem checks it.

A fit is a sequence of routes (trust region, IPOPT, Gauss-Newton steps, the prediction-error filter), each a
loop over evaluations of one shooting problem or passes of one filter, and none of them can be asked from
outside to stop.  :func:`check` sits at the top of those evaluations (:meth:`.shooting.ShootingProblem.evaluate`,
:func:`.tracking.run_filter`) and before every sample of a filter pass: past the deadline it raises
:class:`FitDeadlineExceeded`, and the fit ends at its next evaluation, whatever route it is in.  Where a route
catches the error and another route starts, that one stops at its first evaluation too; the block's ``reached``
tells the caller afterwards that what the fit returned (if anything) is not a finished fit.

The deadline is on the model work done (:mod:`pneusim.solver.work`: the integrator's steps, weighted by the
states and columns each integrates), not on a clock: where a fit stops is then the same on every machine, idle
or loaded.  Work on a thread whose result may be dropped runs on a branch of the count (:func:`pneusim.solver.work.branch`);
a deadline it meets there reaches its caller's blocks only when the caller takes that result (:func:`take`).

A block may also carry a processor-time backstop (``cpu_at_s``) for work the count misses (the optimisers' own
linear algebra, a machine far slower than any in use); it depends on the machine and is meant never to be met
before the work deadline.  Without a block, :func:`check` costs a list lookup.
"""

from __future__ import annotations

import contextlib
import math
import time

from ..errors import FitError
from ..solver import work

__all__ = ["FitDeadlineExceeded", "work_deadline", "check", "checked", "take"]


class FitDeadlineExceeded(FitError):
    """A fit's evaluation was refused: the work deadline (or the processor-time backstop) set by
    :func:`work_deadline` has passed."""


class _Deadline:
    """One :func:`work_deadline` block: its work units, its processor-time backstop, and whether a fit met
    either (``reached``; ``by_backstop``: the backstop first)."""

    def __init__(self, at_units: float, cpu_at_s: float):
        self.at_units, self.cpu_at_s = at_units, cpu_at_s
        self.reached = self.by_backstop = False

    def passed(self) -> bool:
        return work.done() > self.at_units or time.process_time() > self.cpu_at_s


_active: list[_Deadline] = []


@contextlib.contextmanager
def work_deadline(at_units: float, cpu_at_s: float = math.inf):
    """Within the block, fits stop at their next evaluation once :func:`pneusim.solver.work.done` passes
    ``at_units`` or :func:`time.process_time` passes ``cpu_at_s`` (or an enclosing block's); the block's value
    says afterwards whether one did (``.reached``)."""
    block = _Deadline(min([float(at_units)] + [d.at_units for d in _active]),
                      min([float(cpu_at_s)] + [d.cpu_at_s for d in _active]))
    _active.append(block)
    try:
        yield block
    finally:
        _active.remove(block)


def check(backstop_only: bool = False) -> None:
    """Raise :class:`FitDeadlineExceeded` once the innermost deadline has passed (see :func:`work_deadline`);
    ``backstop_only``: once its processor-time backstop has (between the parts of one evaluation that threads
    share, where the count seen mid-way depends on their timing)."""
    if not _active or not (time.process_time() > _active[-1].cpu_at_s if backstop_only else _active[-1].passed()):
        return
    _note_stopped()
    raise FitDeadlineExceeded("the fit was stopped: the work deadline of its caller has passed")


def _note_stopped() -> None:
    """A deadline stopped the calling thread's work: on a branch, the branch records it (its caller learns of it
    when it takes the result, :func:`take`); else every block it has passed is marked reached."""
    if work.on_branch():
        work.current().stopped = True
        return
    for block in _active:
        if not block.reached and block.passed():
            block.reached = True
            block.by_backstop = work.done() <= block.at_units


def checked(step):
    """``step`` itself where no deadline is set, else ``step`` that first calls :func:`check`: for a loop of many
    short steps (a filter pass integrates one sample at a time)."""
    if not _active:
        return step

    def step_checked(*args, **kwargs):
        check()
        return step(*args, **kwargs)
    return step_checked


def take(ledger: work.Ledger) -> None:
    """The result of work on ``ledger`` is taken by the calling thread: its work counts there, and a deadline it
    met reaches the calling thread's blocks."""
    ledger.merge()
    if ledger.stopped:
        _note_stopped()
