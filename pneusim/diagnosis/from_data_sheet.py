"""Far above noise: the candidates screened and confirmed from the data sheet.

Where the fitted nominal model ends more than :data:`~.rules.MODEL_SHORT` times above the sensor noise on its
estimation part, its parameters have bent to make up for the missing physics (a valve offset is taken up by a
static friction several times the rig's), and screening around that optimum misranks: the true effect may
screen near the bottom, and whole fits of every candidate from the data sheet cost many nominal fits
(``docs/decisions/0028``).

Here every candidate gets the fit's pre-fit alone (:func:`pneusim.fit.prefit_recording`): from the data
sheet, with the effect switched on and its parameters free beside the nominal ones, on the
:data:`~.rules.WINDOW_SAMPLES` samples of the estimation part where the nominal model's residual is largest
(:func:`mismatch_window`), beside the nominal model's pre-fit on the same window.  The BIC gain on the window,
``N ln(C_nominal / C_effect) - k ln N``, ranks them (:func:`screen_from_data_sheet`).  The leaders are then
fitted whole from their pre-fit values (:func:`confirm_from_data_sheet`; the nominal parameters from the data
sheet where a pre-fit explained little of the window, :data:`~.rules.PREFIT_START`) and kept by the same test
as any refit.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .candidates import family_of
from .refits import effect_at_prefit, estimation_cost, judge_refit, retry_from_neutral
from .result import CandidateTrial
from .run import WindowScreening
from .rules import (AT_NOISE_ON_WINDOW, DEFER_WINDOW, EXPLAINED, MAX_FITS, MODEL_SHORT, PREFIT_EVALUATIONS,
                    PREFIT_START, RIVAL_WINDOW, WINDOW_SAMPLES, WINDOW_SHOWS_MISMATCH, bic_penalty, is_solver_failure)
from .signatures import evidence_text

__all__ = ["mismatch_window", "one_start_each", "data_sheet_start", "screen_from_data_sheet",
           "confirm_from_data_sheet", "WINDOW_SAMPLES"]


def data_sheet_start(rig, candidate) -> dict | None:
    """Nominal parameters a candidate starts from (its ``start_scale`` on the data sheet's values)."""
    if not candidate.start_scale:
        return None
    return {name: float(rig[name]) * factor for name, factor in candidate.start_scale.items()}


def one_start_each(candidates) -> list:
    """The candidates the screening from the data sheet pre-fits: of each effect's screening starts, the one
    its ``data_sheet_start`` names (the spool at 10 Hz, heat transfer at 50 ms, friction asymmetry at 1, the
    supply line at half the valve's conductance, no load), or all of them where it names none (every leak
    path and every delay: other physics, and a delay has no gradient).  A pre-fit runs to its end from the
    data sheet, where the screening around a nominal optimum takes a few steps only; the starts scanned
    for that (:mod:`.candidates`) end alike here."""
    out = []
    for c in candidates:
        key, value = type(c.effect).data_sheet_start or (None, None)
        if key is None or math.isclose(c.effect.values[key], value, rel_tol=1e-9, abs_tol=1e-12):
            out.append(c)
    return out


def mismatch_window(nominal, recording, noise: dict, samples: int) -> int:
    """The first sample of the ``samples``-long stretch of the estimation part where the fitted nominal model's
    residual (each signal over its noise, squared and summed) is largest: where the screening looks.

    Why not the first samples: the missing physics need not show there (pressure-dependent friction in
    closed-loop steps can leave the first samples explained within the noise while the whole estimation part
    stays five times above it, ``docs/decisions/0028``)."""
    n_est = nominal.n_estimation
    if samples >= n_est:
        return 0
    states = nominal.trajectory()
    squares = np.zeros(n_est)
    for name, sigma in noise.items():
        measured = getattr(recording, name)
        if measured is None:
            continue
        model = states[:n_est, nominal.model.state_names.index(name)]
        squares += np.nan_to_num(((measured[:n_est] - model) / sigma) ** 2)
    cumulative = np.concatenate([[0.0], np.cumsum(squares)])
    return int(np.argmax(cumulative[samples:] - cumulative[:-samples]))


def screen_from_data_sheet(run, candidates: list, signatures: dict, start: int = 0):
    """Pre-fit every candidate from the data sheet on the window from sample ``start`` (``run.stages.prefit``);
    returns ``(trials, variants, ranked, base)``.

    ``variants``: ``{effect: (score, candidate, pre-fit or None)}`` for the best-scoring variant of each
    effect (a leak's path, a delay); ``trials``: a :class:`CandidateTrial` per effect with the evidence;
    ``ranked``: the effects by score.  A candidate whose pre-fit fails is reported in its trial with a
    score of minus infinity.  Once a candidate explains the window down to :data:`~.rules.AT_NOISE_ON_WINDOW`
    times the noise (where the window shows the mismatch), only its look-alikes are pre-fitted after it: no
    other physics can explain more there; the others are not screened (and not in ``variants``).  ``base``:
    the nominal model's pre-fit on the window (:class:`~pneusim.fit.PrefitResult`)."""
    recording, rig = run.recording, run.rig
    options = {"samples": WINDOW_SAMPLES, "validation_fraction": run.baseline.validation_fraction,
               "second_route": False, "max_evaluations": PREFIT_EVALUATIONS, "start": start}
    base = run.stages.prefit(recording, rig, [], **options)
    t0 = float(recording.time_s[start])
    window_shows_it = base.normalised_residual > WINDOW_SHOWS_MISMATCH * AT_NOISE_ON_WINDOW
    n_window = base.n_residuals
    variants, errors, explained_by, singles = {}, {}, None, {}
    for c in one_start_each(candidates):
        if explained_by is not None and c.name not in family_of(explained_by):
            continue
        try:
            pre = run.stages.prefit(recording, rig, [c.effect], start_values=data_sheet_start(rig, c), **options)
            score = n_window * math.log(base.cost / max(pre.cost, 1e-300)) - bic_penalty(c.n_added, n_window)
        except Exception as exc:  # noqa: BLE001 - a candidate that cannot be integrated is reported, not raised
            if not is_solver_failure(exc):
                raise
            pre, score = None, -math.inf
            errors.setdefault(c.name, str(exc))
        run.say(f"from the data sheet on {base.samples} samples from {t0:g} s: {c.label} "
                + (f"ends at {pre.normalised_residual:.3g} times noise (score {score:.0f})" if pre else "failed"))
        singles[c.label] = (c, pre)
        if c.name not in variants or score > variants[c.name][0]:
            variants[c.name] = (score, c, pre)
        if (explained_by is None and window_shows_it and pre is not None
                and pre.normalised_residual <= AT_NOISE_ON_WINDOW):
            explained_by = c.name
            run.say(f"{c.label} explains the window down to the noise: only its look-alikes are screened further")
    run.window = WindowScreening(options, base, window_shows_it, singles)
    trials = {eff: _trial(eff, score, c, pre, base, t0, signatures, errors)
              for eff, (score, c, pre) in variants.items()}
    ranked = sorted(variants, key=lambda k: -variants[k][0])
    return trials, variants, ranked, base


def _trial(eff: str, score: float, c, pre, base, t0: float, signatures: dict, errors: dict) -> CandidateTrial:
    """The trial of an effect pre-fitted from the data sheet: its signatures' evidence, what its pre-fit
    explained, and its pre-fitted values (a searched parameter's from the candidate: a pre-fit holds it)."""
    evidence = evidence_text(eff, signatures)
    if pre is not None:
        evidence += (f"; screening from the data sheet on {base.samples} samples from {t0:g} s, where the nominal "
                     f"fit's residual is largest (it ends far above noise): with it ({c.label}) the pre-fit ends at "
                     f"{pre.normalised_residual:.3g} times the noise against the nominal model's "
                     f"{base.normalised_residual:.3g} (BIC gain {score:.0f})")
    values = {k.split(".", 1)[1]: v for k, v in (pre.estimates.items() if pre else ()) if "." in k}
    values.update({key: c.effect.values[key] for key in type(c.effect).searched})
    return CandidateTrial(eff, score, evidence,
                          status=("not refitted" if pre is not None
                                  else f"screening failed: {errors.get(eff, 'no variant could be fitted')}"),
                          parameters=values, seconds=pre.seconds if pre else None)


class _WholeFits:
    """The whole fits from the data sheet of one diagnosis (:func:`confirm_from_data_sheet`): at most
    :data:`~.rules.MAX_FITS`, each candidate's pre-fit rms on the window, the nominal pre-fit's there."""

    def __init__(self, run, variants: dict, window_nominal_rms: float):
        self.run, self.variants, self.window_nominal_rms = run, variants, window_nominal_rms
        self.budget = MAX_FITS

    def window_rms(self, eff: str) -> float:
        """``eff``'s pre-fit residual rms on the window, noise units (NaN when unknown)."""
        return getattr(self.variants[eff][2], "normalised_residual", math.nan)

    def kept_rms(self) -> float:
        """The lowest estimation residual rms (noise units) of the kept fits; infinity when none is kept."""
        run = self.run
        costs = [estimation_cost(run.refits[k][0], run.noise)[0] for k in run.refits if run.trials[k].kept]
        return run.baseline.rms(min(costs)) if costs else math.inf

    def outclassed(self, eff: str) -> str:
        """Why ``eff`` is not fitted whole: its pre-fit on the window ends more than :data:`~.rules.RIVAL_WINDOW`
        times above the best kept one's (empty when it is fitted)."""
        run, rms = self.run, self.window_rms
        kept = [k for k in run.refits if run.trials[k].kept and math.isfinite(rms(k))]
        if not kept or not math.isfinite(rms(eff)):
            return ""
        best = min(kept, key=rms)
        if not rms(eff) > RIVAL_WINDOW * rms(best):
            return ""
        return (f"not fitted alone: its pre-fit on the window ends at {rms(eff):.3g} times the noise, more than "
                f"{RIVAL_WINDOW:g} times {best}'s {rms(best):.3g} (kept): no rival for the first finding, "
                "screened as a second effect on top of it")

    def fit(self, eff: str) -> None:
        """Fit ``eff`` whole from the data sheet (``run.stages.fit``) and apply the keep test, unless the budget is
        spent, it was fitted, or it is outclassed (then it goes to ``run.second_only``)."""
        run = self.run
        if self.budget <= 0 or eff in run.refits or eff in run.second_only:
            return
        score, c, pre = self.variants[eff]
        trial = run.trials[eff]
        why = self.outclassed(eff)
        if why:
            trial.status = why
            run.second_only[eff] = c
            return
        self.budget -= 1
        run.say(f"fit with {c.label} from the data sheet")
        started = time.perf_counter()
        # the pre-fit's nominal values are a start only where it explained the window: else they are where its
        # evaluations left them, not an optimum
        explained = pre.normalised_residual <= PREFIT_START * self.window_nominal_rms
        nominal_start = {k: v for k, v in pre.estimates.items() if "." not in k} if explained else None
        try:
            fit1 = run.stages.fit(run.recording, run.rig, [effect_at_prefit(c, pre)],
                                  run.baseline.validation_fraction, nominal_start)
        except Exception as exc:  # noqa: BLE001 - a failed fit is reported in the result
            if not is_solver_failure(exc):
                raise
            trial.refitted, trial.status = True, f"fit from the data sheet failed: {exc}"
            trial.seconds = (trial.seconds or 0.0) + time.perf_counter() - started
            return
        cost1, _ = estimation_cost(fit1, run.noise)
        retried = ""
        if run.baseline.fit is not None and self.kept_rms() > EXPLAINED:
            # from the data sheet into a worse basin than the nominal fit's: retried from it, unless a kept fit
            # explains the recording already (a rival could then win by noise at most)
            fit1, cost1, retried = retry_from_neutral(run, c, fit1, cost1)
        judge_refit(run, trial, eff, fit1, cost1, c.n_added, retried, prefix="fitted from the data sheet: ")
        trial.seconds = (trial.seconds or 0.0) + time.perf_counter() - started
        run.refits[eff] = (fit1, c)


def confirm_from_data_sheet(run, ranked: list, variants: dict, window_nominal_rms: float = math.inf) -> None:
    """Fit the leading candidates whole from their pre-fit values and apply the keep test; ``run.trials`` and
    ``run.refits`` are updated in place, and ``run.second_only`` gets the candidates left to the screening on
    top of the first finding.  ``window_nominal_rms``: the nominal model's pre-fit residual rms on the window
    (noise units), which decides a whole fit's start (:data:`~.rules.PREFIT_START`).

    In turn, at most :data:`~.rules.MAX_FITS` fits: (1) the best-ranked member of each family with a positive
    score, up to ``run.max_refits`` families, those without states of their own first (unless
    :data:`~.rules.DEFER_WINDOW` times behind the round's best on the window), stopping once a kept one explains
    the recording down to :data:`~.rules.EXPLAINED` times the noise; (2) the look-alikes of each kept one, or of
    the leader when none was kept (positive score, at most ``run.max_lookalikes`` each), which a window cannot
    always tell apart; (3) while nothing kept brings the model within :data:`~.rules.MODEL_SHORT` times the
    noise, the leaders of the next families.  Once one is kept, a candidate whose pre-fit on the window ends
    more than :data:`~.rules.RIVAL_WINDOW` times above the best kept one's is not fitted whole, a look-alike of
    the kept one or not: it goes to ``run.second_only``.

    Why: the window is where the nominal model's residual is largest, and a candidate that leaves several
    times the kept one's residual there is no rival for the first finding; its whole fit from the data sheet
    only decided whether it was tried as a second effect, which the screening on top of the first finding
    decides anyway; such fits lost alone, and a true second effect among them was never tried on top.  The
    stateless effects first because the stop at :data:`~.rules.EXPLAINED` makes the order a matter of cost
    (a whole fit of an effect with states costs many times one without), but not one far behind on the window
    (``docs/decisions/0029``)."""
    fits = _WholeFits(run, variants, window_nominal_rms)
    positive = [k for k in ranked if variants[k][0] > 0 and variants[k][2] is not None]
    families = []
    for k in positive:
        if family_of(k) not in families:
            families.append(family_of(k))
    leaders = [next(k for k in positive if family_of(k) == f) for f in families]
    first_round = leaders[:max(0, run.max_refits)]
    best_window = min((fits.window_rms(k) for k in first_round if math.isfinite(fits.window_rms(k))), default=math.nan)
    far_behind = lambda k: fits.window_rms(k) > DEFER_WINDOW * best_window  # noqa: E731  (False for NaN)
    first_round = sorted(first_round, key=lambda k: bool(variants[k][1].effect.states) or far_behind(k))
    for eff in first_round:
        fits.fit(eff)
        if fits.kept_rms() <= EXPLAINED:
            break
    for target in run.kept_by_fit() or [k for k in leaders[:1] if k in run.refits]:
        alikes = [k for k in positive if k in family_of(target) and k != target]
        for eff in alikes[:max(0, run.max_lookalikes)]:
            fits.fit(eff)
    for eff in leaders[max(0, run.max_refits):]:
        if fits.kept_rms() <= MODEL_SHORT:
            break
        fits.fit(eff)
