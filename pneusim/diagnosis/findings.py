"""The findings of a diagnosis: effects added on top of the findings so far while the model stays above the noise
(:func:`add_findings`), and each finding as the user reads it, with its parameters as a data sheet gives them
(:func:`make_findings`).

Why on top, by what a candidate explains there: once some findings are in, what another effect must explain is
their residual; a candidate that fitted well alone often explained the same as the first, while a true second
effect that fitted badly alone was never tried (``docs/decisions/0032``).  Every candidate of the vocabulary not
yet found is screened on top of the findings' fit (a few trust-region steps from its neutral start, as in the
first screening); the one that explains most is refitted with the findings, and kept by the keep test against
them; where the findings' fit still ends far above the noise and the warm refit fails, the findings and the
candidate are fitted together from the data sheet instead.  Whether each finding is needed with the others
present is the drop-one test's to say (:mod:`.joint`).
"""

from __future__ import annotations

import math
import time

from ..model.effects import EFFECTS
from .from_data_sheet import data_sheet_start
from .refits import effect_at_screened, effect_parameters, estimation_cost
from .result import Finding
from .rules import EXPLAINED, MIN_EXPLAINED, MODEL_SHORT, ON_TOP_REFITS, bic_penalty, is_solver_failure

__all__ = ["add_findings", "make_findings", "residual_rms", "ON_TOP_REFITS"]


def residual_rms(run, fit) -> float:
    """A fit's estimation residual rms in noise units, continuity defects counted (:func:`.refits.estimation_cost`)."""
    cost, _ = estimation_cost(fit, run.noise)
    return math.sqrt(cost / max(run.baseline.n_residuals, 1))


def _pool(run, members: list) -> dict:
    """The candidates not yet found, by effect: ``{effect: [its variants]}``."""
    pool: dict = {}
    for c in run.candidates:
        if c.name not in members:
            pool.setdefault(c.name, []).append(c)
    return pool


def add_findings(run, members: list, final) -> tuple[list, object]:
    """Effects added on top of ``members`` (their fit ``final``) while the model stays above the noise (its
    estimation residual above :data:`~.rules.EXPLAINED` times it), at most ``run.max_findings`` in all; returns
    ``(members, final)``.

    Each round screens every candidate not yet found on top of ``final`` (``run.candidates``, each effect by its
    best variant) and refits those that explain at least :data:`~.rules.MIN_EXPLAINED` of the findings' cost
    there, most first, at most :data:`~.rules.ON_TOP_REFITS` a round; the first kept joins.  ``run.trials`` say
    what each was found to do."""
    members = list(members)
    while len(members) < max(1, run.max_findings) and residual_rms(run, final) > EXPLAINED:
        pool = _pool(run, members)
        if not pool or not run.can_fit("the screening on top of the findings", 0.3):
            break
        with run.clock.stage("on_top"):
            base_top, scores = _screen_on_top(run, final, pool)
        order = sorted(scores, key=lambda k: -scores[k][1])
        order = [k for k in order if not math.isfinite(scores[k][0]) or scores[k][1] > MIN_EXPLAINED * base_top]
        for rest in set(scores) - set(order):
            run.trials[rest].status += (f"; on top of {', '.join(members)}: screening explains "
                                        f"{scores[rest][0]:.0f} of {base_top:.0f} (at most {MIN_EXPLAINED:g} of it)")
        for rest in order[ON_TOP_REFITS:]:
            run.trials[rest].status += (f"; not refitted on top of {', '.join(members)} (the {ON_TOP_REFITS} that "
                                        "explained most there were)")
        added = None
        run.remember(final)
        for eff in order[:ON_TOP_REFITS]:
            if not run.can_fit(f"the refit of {eff} on top of {', '.join(members)}", 1.0,
                               list(final.effects_) + [scores[eff][2].effect]):
                break
            gain, _, c, screening = scores[eff]
            text = f" (screening explains {gain:.0f} of {base_top:.0f} there)" if math.isfinite(gain) else ""
            with run.clock.stage("on_top"):
                tried = _refit_on_top(run, members, final, eff, effect_at_screened(c, screening), c, text)
            if tried is not None and tried[0]:
                added, final = eff, tried[1]
                break
        if added is None:
            break
        run.trials[added].kept = True
        members.append(added)
    return members, final


def _screen_on_top(run, final, pool: dict) -> tuple[float, dict]:
    """What each effect of ``pool`` (``{effect: [variants]}``) still explains once the findings (``final``) are
    in: ``(base_top, {effect: (gain, score, best variant, its screening)})``, ``base_top`` the findings' own cost on the
    screening window.

    From the findings' own cost, not from where the same steps take it without a candidate (as around the
    nominal optimum): a fit far from noise gains much from those steps alone, and in a few steps a true
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
    for eff, variants in pool.items():
        for c in variants:
            gain, screened = math.inf, {}
            if math.isfinite(base_top):
                try:
                    screened = run.stages.screen(final, run.recording, c, run.noise, run.screen_samples)
                    gain = base_top - screened["cost"]
                except Exception as exc:  # noqa: BLE001
                    if not is_solver_failure(exc):
                        raise
            score = gain - bic_penalty(c.n_added, max(run.n_screen, 2))
            if eff not in scores or score > scores[eff][1]:
                scores[eff] = (gain, score, c, screened)
    return base_top, scores


def _refit_on_top(run, members: list, final, eff: str, effect, c, screened: str):
    """Refit the findings so far (``final``) with ``eff`` on top (``effect``, at its screened values; ``c`` its
    candidate), warm from them, and apply the keep test
    against them; where that fails and the findings' fit ends more than :data:`~.rules.MODEL_SHORT` times above
    noise, the findings and the candidate fitted from the data sheet are tested instead.  Returns ``(kept,
    fit)``, or None when the refit failed (the trial says why)."""
    trial, basis, first = run.trials[eff], run.baseline, ", ".join(members)
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
    if (not ok and math.sqrt(c_prev / max(basis.n_residuals, 1)) > MODEL_SHORT
            and run.can_fit(f"the fit of {first} and {eff} from the data sheet", 1.5,
                            list(final.effects_) + [effect])):
        both = _on_top_from_data_sheet(run, final, c, trial)
        if both is not None:
            fit2, c2 = both
            ok, _, reason = run.stages.keep_test(c_prev, c2, basis.n_residuals, c.n_added, final.fit_percent,
                                                 fit2.fit_percent, basis.floor)
            trial.status += f"; both fitted from the data sheet: {reason}"
    trial.fit_percent, trial.improvement_points = fit2.fit_percent, fit2.fit_percent - final.fit_percent
    trial.parameters, _ = effect_parameters(fit2, eff)
    return ok, fit2


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


def make_findings(run, final, importance: dict) -> list[Finding]:
    """The findings of ``final`` (a fit with the kept effects), most important first: ``importance[effect]`` is
    the validation fit the model loses without it, the others present (:func:`.joint.drop_one`); a lone
    finding's is what it adds to the nominal fit.  Each finding's ``fit_percent`` is the validation fit with all
    of them, its ``improvement_points`` its importance."""
    names = [e.name for e in final.effects_]
    if len(names) == 1:
        importance = {names[0]: final.fit_percent - run.baseline.fit0}
    elif not importance:   # drop-one did not run (the time budget): what the set adds to the nominal fit
        importance = {k: final.fit_percent - run.baseline.fit0 for k in names}
    names.sort(key=lambda k: -importance.get(k, -math.inf))
    out = []
    for eff in names:
        values, errors = effect_parameters(final, eff)
        trial = run.trials[eff]
        out.append(Finding(effect=eff, evidence=trial.evidence + f"; refit: {trial.status}",
                           parameters=_derived(eff, values, final), fit_percent=final.fit_percent,
                           improvement_points=importance.get(eff, math.nan), standard_errors=errors))
    return out


def _derived(name: str, values: dict, fit) -> dict:
    """Parameters a user compares with a data sheet, derived from the fitted ones (the effect's own
    :meth:`~pneusim.model.effects.Effect.derived_parameters`)."""
    cls = EFFECTS.get(name)
    if cls is None:
        return dict(values)
    est = fit.estimates
    return cls.derived_parameters(values, lambda key: est.get(key, fit.rig_.params[key]))
