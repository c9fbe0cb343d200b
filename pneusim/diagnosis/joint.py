"""Several effects fitted together, and each one tested with the others present (drop-one).

**Jointly from the data sheet** (:func:`fit_set_from_data_sheet`).  Where the nominal model ends far above the
noise its parameters have bent to make up for what is missing, and a fit warm from them stays in their basin;
the set chosen on the window (:mod:`.grow`) is fitted whole from the data sheet instead, from the set's
pre-fitted values (the nominal parameters from the pre-fit where it explained the window,
:data:`~.rules.PREFIT_START`), and kept by the keep test against the nominal fit.  A set that fails is
shortened from its last member and fitted again, while the budget allows.

**Drop-one** (:func:`drop_one`).  A finding may only have helped because something else was missing: a
valve offset absorbs part of a leak's steady error until the leak is in.  With all findings in, each one is
refitted out (warm from the findings' fit, the others present) and must pass the keep test against the model
without it; the one that passes least is removed and the rest tested again.  The model without it is judged by
the lowest fit of that set met so far on the estimation part (:meth:`.run.DiagnosisRun.remember`): the refit
out, or the fit the others had before it was added on top, whichever the optimiser took further -- a refit that
only found a better optimum of the others says the finding is not needed, and a refit that ended above their
own earlier fit says nothing against it (``docs/decisions/0032``).  What the validation fit loses when a finding
is dropped is its importance; the findings are reported most important first.
"""

from __future__ import annotations

import math
import time

from .refits import effect_parameters, estimation_cost
from .rules import PREFIT_START, is_solver_failure

__all__ = ["fit_set_from_data_sheet", "judge_against", "drop_one", "Dropped"]


def _names(effects) -> str:
    return ", ".join(e.name for e in effects) or "no effect"


def judge_against(run, before, cost_before: float, after, cost_after: float, n_added: int) -> tuple[bool, str]:
    """The keep test (``run.stages.keep_test``) of fit ``after`` against fit ``before`` (estimation costs given,
    ``n_added`` parameters more); ``(kept, reason)``."""
    basis = run.baseline
    kept, _, reason = run.stages.keep_test(cost_before, cost_after, basis.n_residuals, n_added, before.fit_percent,
                                           after.fit_percent, basis.floor)
    return kept, reason


def _fit(run, effects, nominal_start):
    """One whole fit from the data sheet with ``effects``; ``(fit, cost)`` or ``(None, reason)``."""
    try:
        with run.clock.stage("joint_fits"):
            fit = run.stages.fit(run.recording, run.rig, effects, run.baseline.validation_fraction, nominal_start)
    except Exception as exc:  # noqa: BLE001 - a failed fit is reported in the trials
        if not is_solver_failure(exc):
            raise
        return None, f"failed: {exc}"
    return fit, estimation_cost(fit, run.noise)[0]


def fit_set_from_data_sheet(run, window, window_nominal_rms: float):
    """Fit the set of :class:`.grow.WindowSet` ``window`` whole from the data sheet and apply the keep test
    against the nominal fit; where it fails, the set without its last member, and so on.  Returns ``(members,
    fit)`` of the first set kept, or ``([], None)``; each member's trial says what happened (``run.trials``)."""
    from .grow import nominal_values, set_effects

    basis = run.baseline
    members = list(window.members)
    for k, text in window.log.items():
        if k in run.trials:
            run.trials[k].status = f"chosen on the window: {text}" if k in members else f"on the window: {text}"
    explained = window.prefit.normalised_residual <= PREFIT_START * window_nominal_rms
    start = nominal_values(window.prefit) if explained else None
    while members:
        effects = set_effects(members, window.candidates, window.prefit)
        if not run.can_fit(f"the joint fit of {', '.join(members)}", 1.5, effects):
            break
        run.say(f"fit with {_names(effects)} together from the data sheet")
        started = time.perf_counter()
        fit, cost = _fit(run, effects, start)
        seconds = time.perf_counter() - started
        if fit is None:
            for k in members:
                run.trials[k].status += f"; fitted with {', '.join(members)} from the data sheet: {cost}"
            members.pop()
            continue
        n_added = sum(window.candidates[k].n_added for k in members)
        kept, reason = judge_against(run, basis.fit, basis.cost0, fit, cost, n_added)
        for k in members:
            trial = run.trials[k]
            trial.refitted, trial.kept = True, kept
            trial.status += f"; fitted with {', '.join(members)} from the data sheet ({seconds:.0f} s): {reason}"
            trial.fit_percent, trial.improvement_points = fit.fit_percent, fit.fit_percent - basis.fit0
            trial.parameters, _ = effect_parameters(fit, k)
        if kept:
            return members, fit
        members.pop()
    return [], None


class Dropped:
    """What drop-one measured: ``importance`` (``{effect: validation points lost without it}``), ``without``
    (``{effect: the fit without it}``) and ``removed`` (the effects dropped, in order)."""

    def __init__(self):
        self.importance, self.without, self.removed = {}, {}, []


def _refit_without(run, final, eff: str):
    """``final`` refitted warm with ``eff`` taken out; ``(fit, cost)`` or ``(None, reason)``."""
    others = [e for e in final.effects_ if e.name != eff]
    try:
        with run.clock.stage("drop_one"):
            fit = run.stages.refit(run.recording, run.rig, others, final)
    except Exception as exc:  # noqa: BLE001 - the finding stays when the model without it cannot be fitted
        if not is_solver_failure(exc):
            raise
        return None, f"the model without it could not be fitted: {exc}"
    return fit, estimation_cost(fit, run.noise)[0]


def drop_one(run, final, n_added: dict):
    """Test every effect of ``final`` (a fit with two or more) with the others present; returns ``(final,
    dropped)``: the fit without the effects removed, and the :class:`Dropped` measurements.  ``n_added``:
    ``{effect: parameters it adds}``.  The trials say what each test gave."""
    dropped = Dropped()
    while len(final.effects_) >= 2:
        cost_final = estimation_cost(final, run.noise)[0]
        failing = []
        for e in list(final.effects_):
            if not run.can_fit(f"drop-one of {e.name}", 1.0, [x for x in final.effects_ if x is not e]):
                return final, dropped
            run.say(f"drop-one: {e.name} refitted out, the others present")
            without, cost = _refit_without(run, final, e.name)
            trial = run.trials[e.name]
            if without is None:
                trial.status += f"; drop-one: {cost}"
                continue
            run.remember(without)
            without = run.set_fits[frozenset(k.name for k in without.effects_)]
            cost = estimation_cost(without, run.noise)[0]
            kept, reason = judge_against(run, without, cost, final, cost_final, n_added.get(e.name, 1))
            dropped.importance[e.name] = final.fit_percent - without.fit_percent
            dropped.without[e.name] = without
            trial.status += (f"; drop-one (the others present, {without.fit_percent:.2f} % without it): "
                             + (reason if kept else f"not needed, {reason}"))
            if not kept:
                failing.append(e.name)
        if not failing:
            break
        weakest = min(failing, key=lambda k: dropped.importance.get(k, -math.inf))
        run.trials[weakest].kept = False
        dropped.removed.append(weakest)
        final = dropped.without[weakest]
        run.say(f"drop-one removes {weakest}: the others explain the recording as well without it")
    return final, dropped
