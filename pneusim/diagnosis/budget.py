"""The diagnosis's time budget: no recording runs past it, and one that cannot finish returns what it has.

A diagnosis is a sequence of fits, from seconds to minutes each, and none can be stopped half-way and give a
fit.  :class:`Budget` is asked before each costly step whether the step fits in what is left, the step's
expected cost measured on this recording (a whole fit: the nominal fit's own cost); a step that does not fit is
not started, and one that started is stopped at the budget's end (a deadline every evaluation of a fit checks,
:mod:`pneusim.fit.deadline`).  :func:`gated_stages` puts both in front of every fit and screening a diagnosis
calls: a refused or stopped step raises :class:`TimeBudgetExhausted`, a :class:`~pneusim.errors.PneusimError`,
so every step reports it in its candidate's trial as it reports a failed fit, and goes on with what it has; the
result's ``status`` says which step was refused or stopped.

The budget is given in seconds and counted in model work (:mod:`pneusim.solver.work`: the integrator's steps,
weighted by the states and columns each integrates), at :data:`.rules.WORK_UNITS_PER_S` units a second -- the
rate of the reference machine, a 2-core Xeon VM.  Which steps fit is then the same on every machine, idle or
loaded, and so is the answer; a machine half as fast takes twice as long over it (a processor-time budget bought
it half the search and another answer: ``docs/decisions/0115``, ``0116``).  A processor-time backstop,
:data:`.rules.BUDGET_BACKSTOP` times the budget, ends a search whose work the count misses; the status says when
it did.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import time

from ..errors import PneusimError
from ..fit.deadline import work_deadline
from ..solver import work
from .rules import BUDGET_BACKSTOP, WORK_UNITS_PER_S

__all__ = ["Budget", "TimeBudgetExhausted", "gated_stages"]


class TimeBudgetExhausted(PneusimError):
    """A step of the diagnosis was not started: it would not fit in what is left of the time budget."""


class Budget:
    """At most ``seconds`` (``math.inf``: no limit) for one diagnosis, counted in model work from construction
    (:data:`.rules.WORK_UNITS_PER_S` units a second), with a processor-time backstop."""

    def __init__(self, seconds: float = math.inf):
        if not seconds > 0:
            raise PneusimError(f"the diagnosis's time budget must be a positive number of seconds, got {seconds}")
        self.seconds = float(seconds)
        self.started, self.cpu_started = work.done(), time.process_time()
        #: the first step refused and why (None: none was refused)
        self.stopped: str | None = None
        #: seconds of the budget (used) at which the step running in a :meth:`share` block must end (None: none)
        self.share_ends: float | None = None

    def used(self) -> float:
        """Seconds of the budget used so far: the work done since construction, at the reference rate."""
        return (work.done() - self.started) / WORK_UNITS_PER_S

    def left(self) -> float:
        """Seconds left (negative once overspent)."""
        return self.seconds - self.used()

    def deadline(self):
        """A :func:`pneusim.fit.deadline.work_deadline` block at the budget's end (or the end of the running
        :meth:`share`, where that is earlier), with its backstop."""
        end = self.seconds if self.share_ends is None else min(self.seconds, self.share_ends)
        return work_deadline(self.started + end * WORK_UNITS_PER_S, self.cpu_started + BUDGET_BACKSTOP * self.seconds)

    @contextlib.contextmanager
    def share(self, fraction: float):
        """Within the block, a step may use at most ``fraction`` of the budget left at its start: one that runs
        to the end of its share is stopped there (:func:`gated_stages` raises :class:`TimeBudgetExhausted`) without
        stopping the budget, and what is left stays for the steps after the block."""
        self.share_ends = self.used() + fraction * max(self.left(), 0.0)
        try:
            yield
        finally:
            self.share_ends = None

    def refund(self, since_used: float) -> None:
        """Do not charge the work done since :meth:`used` was ``since_used``: the steps after keep the budget they
        had without it."""
        self.seconds += self.used() - since_used

    def share_binds(self) -> bool:
        """Whether a running :meth:`share` ends before the budget does (a step stopped now met its share's end)."""
        return self.share_ends is not None and self.share_ends < self.seconds

    def check(self, step: str, cost_s: float) -> None:
        """Raise :class:`TimeBudgetExhausted` where ``step``, expected to cost ``cost_s`` seconds of the budget,
        does not fit in what is left; the first refusal is recorded in :attr:`stopped`."""
        if self.stopped is None and self.used() + max(0.0, cost_s) <= self.seconds:
            return
        reason = (f"{step} (expected {cost_s:.0f} s) does not fit in the "
                  f"{max(self.left(), 0.0):.0f} s left of the {self.seconds:.0f} s time budget")
        self.stop(reason)
        raise TimeBudgetExhausted(f"not started: {reason}")

    def stop(self, reason: str) -> None:
        """Record that the budget ran out (``reason``) unless a refusal was recorded first: every later step
        is refused."""
        if self.stopped is None:
            self.stopped = reason

    @property
    def status(self) -> str:
        """``"complete"``, or ``"stopped by the time budget: ..."`` naming the first step refused."""
        return "complete" if self.stopped is None else f"stopped by the time budget: {self.stopped}"


#: the stages a budget gates, and what each costs: a whole fit (True) or a few trust-region steps (False)
_GATED = {"refit": True, "fit": True, "rescue": True, "prefit": False, "screen": False, "polished_costs": False}


def gated_stages(stages, budget: Budget, fit_cost_s: float):
    """``stages`` (:class:`~.estimator.DiagnosisStages`) with every fit and screening asking ``budget`` first:
    a whole fit is expected to cost ``fit_cost_s`` seconds of the budget (the nominal fit's), a pre-fit or a
    screening nothing beyond what is already spent (it is refused only once the budget is overspent).  A step
    that started runs under the budget's end as a deadline (:meth:`Budget.deadline`): a fit
    that would run past it stops at its next evaluation, and the step raises :class:`TimeBudgetExhausted`
    whatever the fit returned (a fit stopped half-way is no result)."""
    def gate(name: str, call, whole: bool):
        step = f"the {name.replace('_', ' ')}"

        @functools.wraps(call)
        def gated(*args, **kwargs):
            budget.check(step, fit_cost_s if whole else 0.0)
            with budget.deadline() as deadline:
                try:
                    out = call(*args, **kwargs)
                except Exception:
                    if not deadline.reached:
                        raise
                    out = None
            if deadline.reached and budget.share_binds() and not deadline.by_backstop:
                raise TimeBudgetExhausted(f"stopped: {step} ran to the end of its share of the time budget "
                                          f"({budget.share_ends:.0f} of {budget.seconds:.0f} s); the rest is left "
                                          "for the steps after it")
            if deadline.reached:
                budget.stop(f"{step} ran to the end of the {budget.seconds:.0f} s time budget and was stopped"
                            + (" (by its processor-time backstop)" if deadline.by_backstop else ""))
                raise TimeBudgetExhausted(f"stopped: {budget.stopped}")
            return out
        return gated

    return dataclasses.replace(stages, **{name: gate(name, getattr(stages, name), whole)
                                          for name, whole in _GATED.items()})
