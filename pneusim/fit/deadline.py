"""A processor-time deadline for fits: a caller that must not run past a point in time (the diagnosis's time
budget) sets one, and every evaluation of a fit's problem checks it.

A fit is a sequence of routes (trust region, IPOPT, Gauss-Newton steps, the prediction-error filter), each a
loop over evaluations of one shooting problem or passes of one filter, and none of them can be asked from
outside to stop.  :func:`check` sits at the top of those evaluations (:meth:`.shooting.ShootingProblem.evaluate`,
:func:`.tracking.run_filter`): past the deadline it raises :class:`FitDeadlineExceeded`, and the fit ends at its
next evaluation, whatever route it is in.  Where a route catches the error and another route starts, that one
stops at its first evaluation too; the block's ``reached`` tells the caller afterwards that what the fit returned
(if anything) is not a finished fit.

The deadline is on :func:`time.process_time` (every thread of the process), process-wide, and set only by
:func:`cpu_deadline`; without one, :func:`check` costs a list lookup.
"""

from __future__ import annotations

import contextlib
import time

from ..errors import FitError

__all__ = ["FitDeadlineExceeded", "cpu_deadline", "check", "checked"]


class FitDeadlineExceeded(FitError):
    """A fit's evaluation was refused: the processor-time deadline set by :func:`cpu_deadline` has passed."""


class _Deadline:
    """One :func:`cpu_deadline` block: its time and whether a fit met it (``reached``)."""

    def __init__(self, at_s: float):
        self.at_s, self.reached = at_s, False


_active: list[_Deadline] = []


@contextlib.contextmanager
def cpu_deadline(at_s: float):
    """Within the block, fits stop at their next evaluation once :func:`time.process_time` passes ``at_s`` (or an
    enclosing block's earlier deadline); the block's value says afterwards whether one did (``.reached``)."""
    block = _Deadline(min([float(at_s)] + [d.at_s for d in _active]))
    _active.append(block)
    try:
        yield block
    finally:
        _active.remove(block)


def check() -> None:
    """Raise :class:`FitDeadlineExceeded` once the innermost deadline has passed (see :func:`cpu_deadline`)."""
    if _active and time.process_time() > _active[-1].at_s:
        for block in _active:
            block.reached = block.reached or time.process_time() > block.at_s
        raise FitDeadlineExceeded("the fit was stopped: the processor-time deadline of its caller has passed")


def checked(step):
    """``step`` itself where no deadline is set, else ``step`` that first calls :func:`check`: for a loop of many
    short steps (a filter pass integrates one sample at a time, and where the model is stiff at the point tried a
    pass can take minutes)."""
    if not _active:
        return step

    def step_checked(*args, **kwargs):
        check()
        return step(*args, **kwargs)
    return step_checked
