"""The findings of a diagnosis: the kept candidate with the best validation fit first, then a second effect
on top of it (:func:`add_findings`), each with its parameters as a user compares them with a data sheet; or,
with nothing kept, the ``other`` finding (:func:`other_finding`).
"""

from __future__ import annotations

import math
import time

from ..model.effects import EFFECTS
from .from_data_sheet import data_sheet_start
from .refits import effect_at_screened, effect_parameters, estimation_cost
from .result import CandidateTrial, Finding
from .rules import MIN_EXPLAINED, MODEL_SHORT, ON_TOP_REFITS, OTHER_RESIDUAL, bic_penalty, is_solver_failure

__all__ = ["add_findings", "other_finding", "ON_TOP_REFITS"]


def add_findings(run, kept: list) -> tuple[list, object]:
    """The first finding (the kept candidate with the best validation fit, ``kept[0]``) and a second effect on
    top of it; returns ``(findings, final fit)``.

    The other kept candidates, and those of ``run.second_only`` (not fitted alone), are all screened on top of
    the first finding's fit; the one that explains most of the residual there is refitted together with it
    while it explains at least :data:`~.rules.MIN_EXPLAINED` of it (at most :data:`~.rules.ON_TOP_REFITS`
    refits, the rest screened again whenever the findings' fit changes), and kept when it passes the keep test
    against the findings before it (and against those refitted alone: :func:`_second_effect_needed`).
    ``run.trials`` are updated in place.

    Why by the screening on top, not by the fit alone: once the first finding is in, what a second effect
    must explain is the first finding's residual, and a candidate that fitted well alone often explained
    the same as the first, while a true second effect that fitted badly alone was never tried
    (``docs/decisions/0032``)."""
    first = kept[0]
    final = run.refits[first][0]
    findings = [_finding(first, final, run.baseline.fit0, run.trials[first])]
    pool = {eff: run.refits[eff][1] for eff in kept[1:]}
    pool.update(run.second_only)
    scores: dict = {}   # {effect: (gain, score)} on top of the current findings, against base_top
    tried_on_top = 0
    while pool and len(findings) < run.max_findings:
        if tried_on_top >= ON_TOP_REFITS:
            for rest in pool:
                run.trials[rest].status += (f"; not refitted on top of {first} (the {ON_TOP_REFITS} that explained "
                                            "most there were)")
                run.trials[rest].kept = False
            break
        if not scores:
            base_top, scores = _screen_on_top(run, final, pool)
        eff = max(pool, key=lambda k: scores[k][1])
        gain, score_top = scores[eff]
        if math.isfinite(gain) and not score_top > MIN_EXPLAINED * base_top:
            for rest in pool:
                run.trials[rest].status += (f"; on top of {first}: screening explains {scores[rest][0]:.0f} of "
                                            f"{base_top:.0f} (score {scores[rest][1]:.0f} <= {MIN_EXPLAINED:g} of "
                                            "it): not refitted")
                run.trials[rest].kept = False
            break
        c = pool.pop(eff)
        tried_on_top += 1
        screened = f" (screening explains {gain:.0f} of {base_top:.0f} there)" if math.isfinite(gain) else ""
        tried = _refit_on_top(run, first, final, eff, c, screened)
        if tried is None:
            continue
        ok, fit2, c_prev, c2 = tried
        if ok:
            previous = final
            ok, final = _second_effect_needed(run, final, c_prev, fit2, c2, eff, c.n_added, findings)
            if final is not previous:
                scores = {}   # the rest are screened again on top of the better optimum
        if ok:
            run.trials[eff].kept = True
            findings.append(_finding(eff, fit2, final.fit_percent, run.trials[eff]))
            final = fit2
    return findings, final


def _screen_on_top(run, final, pool: dict) -> tuple[float, dict]:
    """What each candidate of ``pool`` still explains once the findings (``final``) are in: ``(base_top,
    {effect: (gain, score)})``, ``base_top`` the findings' own cost on the screening window.

    A refit on top costs as much as the first; look-alikes of the first usually explain nothing more.  From
    the findings' own cost, not from where the same steps take it without a candidate (as around the nominal
    optimum): a first finding far from noise gains much from those steps alone, and in a few steps a true
    second effect may not get past them.  Each from the effect's neutral start, as in the first screening:
    the trust region then only goes downhill from the findings' optimum.  Where the findings cannot be
    screened, the refits decide in the order given; a candidate that cannot be screened gets an infinite gain
    (its refit decides)."""
    try:
        base_top = run.stages.screen(final, run.recording, None, run.noise, run.screen_samples)["cost"]
    except Exception as exc:  # noqa: BLE001
        if not is_solver_failure(exc):
            raise
        base_top = math.nan
    scores = {}
    for eff, c in pool.items():
        gain = math.inf
        if math.isfinite(base_top):
            try:
                gain = base_top - run.stages.screen(final, run.recording, c, run.noise, run.screen_samples)["cost"]
            except Exception as exc:  # noqa: BLE001
                if not is_solver_failure(exc):
                    raise
        scores[eff] = (gain, gain - bic_penalty(c.n_added, max(run.n_screen, 2)))
    return base_top, scores


def _refit_on_top(run, first: str, final, eff: str, c, screened: str):
    """Refit the findings so far (``final``) with ``eff`` on top, warm from them, and apply the keep test
    against them; where that fails and the findings' fit ends more than :data:`~.rules.MODEL_SHORT` times above
    noise, both fitted from the data sheet are tested instead.  Returns ``(kept, fit, cost before, cost
    after)``, or None when the refit failed (the trial says why)."""
    trial, basis = run.trials[eff], run.baseline
    effect = effect_at_screened(c, {"parameters": trial.parameters})
    run.say(f"refit with {first} and {eff}")
    trial.kept, trial.refitted = False, True
    started = time.perf_counter()
    try:
        fit2 = run.stages.refit(run.recording, run.rig, list(final.effects_) + [effect], final)
    except Exception as exc:  # noqa: BLE001
        if not is_solver_failure(exc):
            raise
        trial.status += f"; with {first}: refit failed: {exc}"
        return None
    finally:
        trial.seconds = (trial.seconds or 0.0) + time.perf_counter() - started
    c_prev, _ = estimation_cost(final, run.noise)
    c2, _ = estimation_cost(fit2, run.noise)
    ok, _, reason = run.stages.keep_test(c_prev, c2, basis.n_residuals, c.n_added, final.fit_percent,
                                         fit2.fit_percent, basis.floor)
    trial.status += f"; on top of {first}{screened}: {reason}"
    if not ok and math.sqrt(c_prev / max(basis.n_residuals, 1)) > MODEL_SHORT:
        both = _on_top_from_data_sheet(run, final, c, trial)
        if both is not None:
            fit2, c2 = both
            ok, _, reason = run.stages.keep_test(c_prev, c2, basis.n_residuals, c.n_added, final.fit_percent,
                                                 fit2.fit_percent, basis.floor)
            trial.status += f"; both fitted from the data sheet: {reason}"
    return ok, fit2, c_prev, c2


def _on_top_from_data_sheet(run, final, c, trial):
    """Fit the findings so far (``final``'s effects, at their fitted values) and candidate ``c`` (at its own
    start) together from the data sheet (``run.stages.fit``); returns ``(fit, estimation cost)``, or None when
    the fit fails.

    Why: used where the findings' fit still ends more than :data:`~.rules.MODEL_SHORT` times above the noise
    and the refit on top of it failed the test.  Its nominal parameters have then bent to make up for the
    physics still missing, as the nominal fit's had (see :mod:`.from_data_sheet`), and a refit warm from them
    stays in their basin, its result decided by its start (``docs/decisions/0032``)."""
    run.say(f"refit with {', '.join(e.name for e in final.effects_)} and {c.name} from the data sheet")
    started = time.perf_counter()
    try:
        fit2 = run.stages.fit(run.recording, run.rig, list(final.effects_) + [c.effect],
                              run.baseline.validation_fraction, data_sheet_start(run.rig, c))
    except Exception as exc:  # noqa: BLE001 - a failed fit is reported in the result
        if not is_solver_failure(exc):
            raise
        trial.status += f"; both fitted from the data sheet: failed: {exc}"
        return None
    finally:
        trial.seconds = (trial.seconds or 0.0) + time.perf_counter() - started
    return fit2, estimation_cost(fit2, run.noise)[0]


def _second_effect_needed(run, final, cost_final: float, fit2, cost2: float, eff: str, n_added: int,
                          findings: list) -> tuple:
    """Whether ``eff``, kept on top of the findings so far (``final``, estimation cost ``cost_final``;
    refitted with ``eff`` as ``fit2``, cost ``cost2``), is needed, or whether the refit on top only found a
    better optimum of the findings so far: those alone are refitted warm from ``fit2``, and where that
    refit ends below ``final`` on the estimation part, ``eff`` must pass the keep test against it too.
    Returns ``(needed, final)``, ``final`` replaced by that refit when ``eff`` is not needed (the last
    finding then rebuilt on it).

    Why: a refit on top runs the optimiser on from the first finding's optimum with one more parameter, and
    where that first fit had stopped short, the gain is the optimiser's.  Where the refit alone ends above
    ``final`` on the estimation part (what the fit minimises), ``final`` had not stopped short, and the test
    ``eff`` passed against it stands: tested against that refit instead, a true second effect can fall just
    short of the threshold (``docs/decisions/0032``)."""
    trials, noise, basis = run.trials, run.noise, run.baseline
    run.say(f"{eff} kept on top: the findings before it refitted alone from there")
    try:
        alone = run.stages.refit(run.recording, run.rig, list(final.effects_), fit2)
        cost_alone, _ = estimation_cost(alone, noise)
    except Exception as exc:  # noqa: BLE001 - the refit on top stands
        if not is_solver_failure(exc):
            raise
        return True, final
    if not cost_alone < cost_final:
        trials[eff].status += (f"; the findings before it refitted alone from that optimum end above their own fit "
                               f"on the estimation part ({cost_alone:.0f} >= {cost_final:.0f}; validation "
                               f"{alone.fit_percent:.2f} %): they had not stopped short, the test above stands")
        return True, final
    needed, _, reason = run.stages.keep_test(cost_alone, cost2, basis.n_residuals, n_added, alone.fit_percent,
                                             fit2.fit_percent, basis.floor)
    trials[eff].status += (f"; against the findings before it refitted alone from that optimum "
                           f"({alone.fit_percent:.2f} %): {reason}")
    if needed:
        return True, final
    last = findings[-1]
    trials[last.effect].status += (f"; refitted from the optimum found with {eff} on top: validation "
                                   f"{final.fit_percent:.2f} -> {alone.fit_percent:.2f} %")
    findings[-1] = _finding(last.effect, alone, last.fit_percent - last.improvement_points, trials[last.effect])
    return False, alone


def other_finding(nominal, noise: dict, windows) -> Finding | None:
    """The ``other`` finding where nothing of the vocabulary was kept: the nominal fit's residuals on its
    estimation part above :data:`~.rules.OTHER_RESIDUAL` times the sensor noise, in mismatch windows; else None.

    The residuals alone, without the continuity defects a fit that ended in the penalty form left open (those
    count in the keep test's costs, see :func:`.refits.estimation_cost`): the defects' weight is the penalty's,
    not a multiple of the noise, and they say the optimiser stopped short, not that physics is missing; a
    control whose residuals end near the noise would otherwise be reported as ``other``
    (``docs/decisions/0031``)."""
    cost, count = estimation_cost(nominal, noise, defects=False)
    ratio = math.sqrt(cost / max(count, 1))
    if not (ratio > OTHER_RESIDUAL and windows):
        return None
    conditions = {}
    for w in windows:
        conditions[w.condition] = conditions.get(w.condition, 0.0) + (w.t_end_s - w.t_start_s)
    where = max(conditions, key=conditions.get)
    return Finding(
        effect="other",
        evidence=(f"the fitted nominal model leaves a residual of {ratio:.1f} times the sensor noise on the "
                  f"estimation part, in {len(windows)} window(s), longest in '{where}'; no vocabulary effect "
                  "passed the test (see the candidates)"),
        parameters={}, fit_percent=nominal.fit_percent, improvement_points=0.0)


def _finding(eff: str, fit, fit_before: float, trial: CandidateTrial) -> Finding:
    values, errors = effect_parameters(fit, eff)
    return Finding(effect=eff, evidence=trial.evidence + f"; refit: {trial.status}",
                   parameters=_derived(eff, values, fit), fit_percent=fit.fit_percent,
                   improvement_points=fit.fit_percent - fit_before, standard_errors=errors)


def _derived(name: str, values: dict, fit) -> dict:
    """Parameters a user compares with a data sheet, derived from the fitted ones (the effect's own
    :meth:`~pneusim.model.effects.Effect.derived_parameters`)."""
    cls = EFFECTS.get(name)
    if cls is None:
        return dict(values)
    est = fit.estimates
    return cls.derived_parameters(values, lambda key: est.get(key, fit.rig_.params[key]))
