"""The refits and what they are judged by: the sensor noise, the estimation cost, the whole fits a diagnosis
runs (nominal, warm from a fit, from the data sheet), the retry from an effect's neutral value, and the keep
test applied to a refit (:func:`judge_refit`; the test itself is :func:`.rules.passes_test`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..fit import fit_recording, noise_std_estimate
from ..fit.rules import POSITION_NOISE_FLOOR, PRESSURE_NOISE_FLOOR_PA
from ..model import make_effect
from .candidates import Candidate, neutral_effect
from .rules import DATA_SHEET_FIT_RESCUE, DATA_SHEET_FIT_STARTS, DEFECT_WEIGHT, is_solver_failure

__all__ = ["noise_levels", "estimation_cost", "fit_nominal", "refit", "fit_from_data_sheet", "with_rescue_routes",
           "rescued", "retry_from_neutral", "judge_refit", "effect_parameters", "effect_at_screened", "effect_at_prefit"]


def noise_levels(recording, rig) -> dict:
    """Sensor noise std per measured signal: the rig file's ``[sensors]``, else an estimate from the data,
    never below the fit's floors (the same rule as the fit)."""
    out = {}
    signals = {"position_m": recording.position_m}
    if recording.has_pressures:
        signals.update(pressure_a_Pa=recording.pressure_a_Pa, pressure_b_Pa=recording.pressure_b_Pa)
    for name, values in signals.items():
        from_rig = float(rig.params.get("position_noise_std_m" if name == "position_m" else "pressure_noise_std_Pa", 0.0))
        floor = rig.stroke_m * POSITION_NOISE_FLOOR if name == "position_m" else PRESSURE_NOISE_FLOOR_PA
        out[name] = max(from_rig if from_rig > 0 else noise_std_estimate(values), floor)
    return out


def estimation_cost(fit, noise: dict, defects: bool = True) -> tuple[float, int]:
    """``(C, N)``: residual sum of squares of a fit's estimation part in noise units, plus (with ``defects``)
    its continuity defects weighted as in the fit's penalty form (:data:`~.rules.DEFECT_WEIGHT`), and the
    number of residuals.

    Why the defects: a fit that ends in the penalty form (IPOPT's constrained run rejected) may leave
    segments discontinuous, and its residual alone is then lower than any continuous model's: every refit,
    which closes them, would end above it, and no refit could pass the test.  The penalty form's own
    objective is the measure both fits minimised; at a fit with continuity constraints it is the residual
    sum (``docs/decisions/0031``)."""
    rec = fit.recording
    cost, count = 0.0, 0
    for name, rms in fit.sigma.items():
        values = getattr(rec, name)[:fit.n_estimation]
        n = int(np.sum(np.isfinite(values)))
        cost += n * (float(rms) / noise[name]) ** 2
        count += n
    if defects:
        cost += DEFECT_WEIGHT ** 2 * float(fit.solver.get("defect_sum_squares", 0.0))
    return cost, count


def fit_nominal(recording, rig, validation_fraction: float):
    """The nominal fit: the rig's free parameters, no effect, the last ``validation_fraction`` never fitted."""
    return fit_recording(recording, rig, validation_fraction=validation_fraction, quiet=True)


def refit(recording, rig, effects, warm, start_values=None):
    """The whole fit with ``effects`` switched on, warm-started from the fit ``warm`` (and from
    ``start_values`` for the parameters named there), on the warm fit's estimation/validation split."""
    return fit_recording(recording, rig, effects, warm_start=warm, start_values=start_values, quiet=True)


def fit_from_data_sheet(recording, rig, effects, validation_fraction: float, start_values=None):
    """The whole fit with ``effects`` switched on from the data sheet (and from ``start_values`` for the
    parameters named there), one start (:data:`~.rules.DATA_SHEET_FIT_STARTS`), without the fit's rescue routes
    (:data:`~.rules.DATA_SHEET_FIT_RESCUE`)."""
    return fit_recording(recording, rig, effects, validation_fraction=validation_fraction,
                         starts=DATA_SHEET_FIT_STARTS, quiet=True, start_values=start_values,
                         rescue=DATA_SHEET_FIT_RESCUE)


def with_rescue_routes(recording, rig, fit, validation_fraction: float):
    """``fit`` fitted again as it was started (its effects at their start values, every free parameter from its
    start: :attr:`~pneusim.fit.ParameterEstimate.start`), with the fit's rescue routes
    (:mod:`pneusim.fit.rescue_routes`), which the fits from the data sheet skip (:data:`~.rules.DATA_SHEET_FIT_RESCUE`).
    From a fit from the data sheet this is that fit with the routes: the same steps up to them."""
    return fit_recording(recording, rig, fit.effects_, validation_fraction=validation_fraction,
                         starts=DATA_SHEET_FIT_STARTS, quiet=True,
                         start_values={name: p.start for name, p in fit.parameters.items()}, rescue=True)


def rescued(run, fit, leaves_physics, where: str):
    """``fit`` fitted again with the fit's rescue routes (``run.stages.rescue``,
    :func:`.refits.with_rescue_routes`) where it skipped them (fitted from the data sheet, or warm from another fit)
    and ``leaves_physics(fit)``; the new fit where it ends lower on the estimation part, else ``fit``.  Each rescue
    that runs is recorded in ``run.rescues`` (``where``: the step that asked for it; the JSON's ``rescues``), also
    one that failed or that the time budget stopped.

    Why: the candidates' fits skip the routes (:data:`~.rules.DATA_SHEET_FIT_RESCUE`), which find the optimum of
    a right model on a recording too chaotic for the shooting problem's landscape, and cost as much as the fit
    itself; only the fit the search goes on from (the first finding's, or a pair's found jointly) and the one
    ``other`` is said on get them.
    A right first finding left above noise without them sends the search on top looking for physics that is not
    missing."""
    if fit.solver.get("rescue", True) or not leaves_physics(fit):
        return fit
    run.say(f"fit with {', '.join(e.name for e in fit.effects_)} again, with the rescue routes "
            f"(validation fit {fit.fit_percent:.2f} %)")
    def cost_and_rms(f):     # the keep test's estimation cost (defects included), and its rms in noise units
        cost, n = estimation_cost(f, run.noise)
        return cost, math.sqrt(cost / max(n, 1))

    cost, rms = cost_and_rms(fit)
    record = {"where": where, "effects": [e.name for e in fit.effects_], "fit_percent_before": fit.fit_percent,
              "estimation_rms_before": rms}
    run.rescues.append(record)
    started = time.perf_counter()
    try:
        again = run.stages.rescue(run.recording, run.rig, fit, run.baseline.validation_fraction)
    except Exception as exc:  # noqa: BLE001 - a failed fit leaves the fit as it was
        failed = is_solver_failure(exc)    # else the time budget's stop ("stopped: ...", "not started: ...")
        record.update(kept=False, outcome=f"failed: {exc}" if failed else str(exc),
                      seconds=time.perf_counter() - started)
        if not failed:
            raise
        return fit
    cost_again, rms_again = cost_and_rms(again)
    kept = cost_again < cost
    record.update(fit_percent_after=again.fit_percent, estimation_rms_after=rms_again, kept=kept,
                  outcome="kept: ends lower on the estimation part" if kept else
                  "not kept: ends no lower on the estimation part", seconds=time.perf_counter() - started)
    return again if kept else fit


def retry_from_neutral(run, candidate: Candidate, fit1, cost1: float):
    """A refit nests the nominal model: one that ends above the nominal fit's estimation residual
    (``run.baseline.cost0``) was led into a worse basin by its start (a screened value, or the data sheet);
    ``cost1`` is the refit's.  Once more from the effect's neutral value, warm from the nominal fit
    (``run.baseline.fit``: its optimum is then the start, and the refit can only go down from it).  Returns
    ``(fit, cost, note)``: the lower of the two, and a note for the trial's status (empty when nothing was
    retried: the refit is below the nominal residual, or the effect has no neutral value)."""
    cost0 = run.baseline.cost0
    neutral = neutral_effect(candidate)
    if not cost1 > cost0 or neutral is None:
        return fit1, cost1, ""
    run.say(f"refit with {candidate.label} ended above the nominal residual ({cost1:.0f} > {cost0:.0f}); again "
            f"from {candidate.name} at its neutral value")
    try:
        again = run.stages.refit(run.recording, run.rig, [neutral], run.baseline.fit)
        cost_again, _ = estimation_cost(again, run.noise)
    except Exception as exc:  # noqa: BLE001 - the first refit stands
        if not is_solver_failure(exc):
            raise
        again, cost_again = None, math.inf
    note = (f"; refitted from its start to {cost1:.0f} > nominal {cost0:.0f}, again from the neutral value "
            f"to {cost_again:.0f}")
    if cost_again < cost1:
        return again, cost_again, note
    return fit1, cost1, note


def judge_refit(run, trial, eff: str, fit1, cost1: float, n_added: int, note: str = "", prefix: str = "") -> bool:
    """Apply the keep test (``run.stages.keep_test``) to a refit of ``eff`` (``fit1``, estimation cost ``cost1``)
    against the nominal fit (``run.baseline``: its cost, residual count, validation fit and noise floor) and
    record it in ``trial``: status ``prefix + reason + note``, fit, improvement, cost drop, threshold and the
    effect's parameters (``trial.seconds`` is the caller's).  Returns whether it is kept."""
    basis = run.baseline
    kept, threshold, reason = run.stages.keep_test(basis.cost0, cost1, basis.n_residuals, n_added, basis.fit0,
                                                   fit1.fit_percent, basis.floor)
    trial.refitted, trial.kept, trial.status = True, kept, prefix + reason + note
    trial.fit_percent, trial.improvement_points = fit1.fit_percent, fit1.fit_percent - basis.fit0
    trial.estimation_cost_drop, trial.threshold = basis.cost0 - cost1, threshold
    trial.parameters, _ = effect_parameters(fit1, eff)
    return kept


def effect_parameters(fit, effect_name: str) -> tuple[dict, dict]:
    """The fitted parameters of ``effect_name`` in ``fit`` (without the prefix), with standard errors;
    the options the effect reports (:meth:`~pneusim.model.effects.Effect.reported_options`) as strings.
    A parameter the effect finds by a grid search (``searched``) is reported with the scan's error."""
    values, errors = {}, {}
    for e in fit.effects_:
        if e.name != effect_name:
            continue
        cls = type(e)
        values.update(cls.reported_options(e.option_values))
        for k, v in e.values.items():
            q = f"{e.name}.{k}"
            searched = k in cls.searched
            if q in fit.parameters or searched:
                values[k] = float(v)
                p = fit.parameters.get(q)
                errors[k] = (p.std if p is not None and math.isfinite(p.std) else None)
                if searched:   # scanned, not fitted: from the scan's curvature (:mod:`.delay`)
                    errors[k] = fit.solver.get("delay_scan", {}).get("std_s")
    return values, errors


def effect_at_screened(c: Candidate, screened: dict):
    """The candidate's effect with its screened parameter values (``screened["parameters"]``) as starting
    values, inside the effect's physical range."""
    values = {k: v for k, v in c.effect.values.items()}
    for q, v in screened.get("parameters", {}).items():
        key = q.split(".", 1)[1] if "." in q else q
        if key in values and isinstance(v, (int, float)) and math.isfinite(v):
            values[key] = float(v)
    # a screening step may end on a bound where the effect is absent: the refit starts at least at the effect's floor
    for key, floor in type(c.effect).refit_start_floor.items():
        values[key] = max(values[key], floor)
    # a screening step may leave a parameter just outside the effect's physical range: start inside it
    for key, bounds in getattr(type(c.effect), "ranges", {}).items():
        if key in values and bounds is not None:
            lo, hi = bounds[0], bounds[1]
            span = 1e-6 * max(abs(values[key]), 1e-9)
            if values[key] < lo or (values[key] == lo and not bounds[2]):
                values[key] = lo if bounds[2] else lo + span
            if values[key] > hi or (values[key] == hi and not bounds[3]):
                values[key] = hi if bounds[3] else hi - span
    return make_effect(c.name, **c.effect.option_values, **values)


def effect_at_prefit(candidate: Candidate, pre) -> object:
    """The candidate's effect with its pre-fitted parameter values (``pre``: a
    :class:`~pneusim.fit.PrefitResult`, or None)."""
    values = dict(candidate.effect.values)
    for key, value in (pre.estimates.items() if pre else ()):
        if key.startswith(candidate.name + "."):
            values[key.split(".", 1)[1]] = value
    return make_effect(candidate.name, **candidate.effect.option_values, **values)
