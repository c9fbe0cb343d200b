"""Near noise: the candidates screened around the nominal optimum and confirmed by refits warm from it.

Where the fitted nominal model ends within :data:`~.rules.MODEL_SHORT` times the sensor noise, its
parameters are close to the rig's and the missing physics is what the residual holds.  Every candidate
(each variant of an effect: a leak's path, a delay of the scan) is switched on at a small value beside the
nominal fit's parameters and states, and a few trust-region steps on the first
:data:`~.rules.SCREEN_SAMPLES` estimation samples (:func:`.candidates.screen`) measure how much of the
residual it explains beyond what the same steps take without it (:func:`.candidates.polished_costs`): its
score is that likelihood gain less ``k ln N`` (:func:`screen_around_nominal`).  The leading candidates, one
per look-alike family, then get a whole refit warm from the nominal fit (:func:`confirm_around_nominal`) and
are kept by the keep test (:func:`.rules.passes_test`).  Far above noise the nominal parameters have bent to
make up for the missing physics and this ranking misleads: :mod:`.from_data_sheet` is used instead.
"""

from __future__ import annotations

import math
import time

from .candidates import Candidate, family_of, screen_evaluations
from .delay import ScreenedDelays
from .refits import effect_at_screened, estimation_cost, judge_refit, retry_from_neutral
from .result import CandidateTrial
from .rules import MIN_EXPLAINED, RELATIVE_SCORE, bic_penalty, is_solver_failure
from .signatures import evidence_text

__all__ = ["screen_around_nominal", "confirm_around_nominal", "leading_candidates", "RELATIVE_SCORE",
           "MIN_EXPLAINED"]


def screen_around_nominal(run, candidates: list, signatures: dict):
    """Screen every candidate from the nominal optimum (``run.baseline.fit``); returns ``(trials, variants,
    ranked, base_cost)``.

    A candidate's gain is its cost after the screening's steps (``run.stages.screen``) below the cost the
    same steps reach without it (``run.stages.polished_costs``).

    ``variants``: ``{effect: (score, candidate, screening)}`` for the best-scoring variant of each
    effect, the screened delays refined to the best one (:class:`.delay.ScreenedDelays`);
    ``trials``: a :class:`CandidateTrial` per effect with the evidence; ``ranked``: the effects by
    score; ``base_cost``: the nominal model's cost on the screening window after those steps.
    ``run.n_screen`` is the residual count of the window (the ``ln N`` of the score).  A candidate that
    cannot be integrated has a score of minus infinity and says why in its trial."""
    nominal, recording, noise, samples = run.baseline.fit, run.recording, run.noise, run.screen_samples
    base = run.stages.screen(nominal, recording, None, noise, samples)
    polished = run.stages.polished_costs(nominal, recording, noise, samples)
    variants: dict[str, tuple[float, Candidate, dict]] = {}
    delays = ScreenedDelays()
    for c in candidates:
        try:
            s = run.stages.screen(nominal, recording, c, noise, samples)
            gain = polished[screen_evaluations(c)] - s["cost"]
        except Exception as exc:  # noqa: BLE001 - a candidate that cannot be integrated is reported, not raised
            if not is_solver_failure(exc):
                raise
            s, gain = {"parameters": {}, "seconds": None, "error": str(exc)}, -math.inf
        score = gain - bic_penalty(c.n_added, max(run.n_screen, 2))
        delays.add(c, gain)
        if c.name not in variants or score > variants[c.name][0]:
            variants[c.name] = (score, c, s)
    delays.refine(variants, recording.sample_time_s)
    trials = {eff: _trial(eff, score, c, s, signatures, base["cost"], polished, run.n_screen)
              for eff, (score, c, s) in variants.items()}
    ranked = sorted(variants, key=lambda k: -variants[k][0])
    return trials, variants, ranked, min(polished.values())


def _trial(eff: str, score: float, c: Candidate, s: dict, signatures: dict, base_cost: float, polished: dict,
           n_screen: int) -> CandidateTrial:
    """The trial of a screened effect: its signatures' evidence and what its screening explained."""
    evidence = evidence_text(eff, signatures)
    if math.isfinite(score):
        steps = screen_evaluations(c)
        evidence += (f"; screening: switching it on ({c.label}) explains "
                     f"{score + bic_penalty(c.n_added, max(n_screen, 2)):.0f} of the normalised residual sum "
                     f"of squares {base_cost:.0f}, beyond the {base_cost - polished[steps]:.0f} that "
                     f"the same {steps} steps take without it")
    return CandidateTrial(eff, score, evidence,
                          status="screening failed: " + s["error"] if "error" in s else "not refitted",
                          parameters=dict(s.get("parameters", {})), seconds=s.get("seconds"))


def leading_candidates(ranked: list, variants: dict, base_cost: float) -> list:
    """The effects worth a refit: a score above :data:`~.rules.RELATIVE_SCORE` of the best and above
    :data:`~.rules.MIN_EXPLAINED` of ``base_cost`` (and above zero), in screening order."""
    top = variants[ranked[0]][0] if ranked else 0.0
    least = max(MIN_EXPLAINED * base_cost, RELATIVE_SCORE * top, 0.0)
    return [k for k in ranked if variants[k][0] > least]


def confirm_around_nominal(run, ranked: list, variants: dict, base_cost: float) -> None:
    """Refit the leading candidates (:func:`leading_candidates`) warm from the nominal fit and apply the keep
    test; ``run.trials`` and ``run.refits`` are updated in place.

    In turn: (1) the best-screened member of each leading family, up to ``run.max_refits``; when none is
    kept, the next families by screening order with a positive score, up to ``run.max_refits`` in all;
    (2) the look-alikes of every kept one, best validation fit first (of the leader when none was kept),
    those with a positive score, at most ``run.max_lookalikes`` each.

    Why: distinct hypotheses first, since a few trust-region steps rank look-alikes unreliably and an
    open-loop drift inflates the scores of flexible effects; far from the optimum a flexible effect may
    dwarf the rest in the screening alone, so when nothing leading is kept the next families get their
    refits too; and the look-alikes of every kept one, not only the winner's, since a law mimicking another
    (a friction asymmetry at its bound mimicking a load) may be kept and win (``docs/decisions/0030``).
    Only look-alikes that explained something in the screening: one that made the residual worse there is
    no rival, and its refit from that start wanders."""
    chosen, families_seen = [], set()

    def confirm_family_leaders(pool):
        """Refit the first of each family not yet refitted in ``pool`` (screening order), up to max_refits."""
        for k in pool:
            if len(chosen) >= max(0, run.max_refits):
                return
            if family_of(k) not in families_seen:
                families_seen.add(family_of(k))
                chosen.append(k)
                _confirm(run, k, variants[k])

    confirm_family_leaders(leading_candidates(ranked, variants, base_cost))
    if not any(run.trials[k].kept for k in chosen):
        confirm_family_leaders([k for k in ranked if variants[k][0] > 0])
    for target in run.kept_by_fit() or chosen[:1]:
        alikes = [k for k in ranked if k in family_of(target) and k != target and not run.trials[k].refitted
                  and variants[k][0] > 0]
        for eff in alikes[:max(0, run.max_lookalikes)]:
            _confirm(run, eff, variants[eff])


def _confirm(run, eff: str, variant: tuple) -> None:
    """Refit with ``eff`` warm from the nominal fit, from its screened values, and apply the keep test."""
    score, c, s = variant
    trial = run.trials[eff]
    t0 = time.perf_counter()
    run.say(f"refit with {c.label}")
    try:
        fit1 = run.stages.refit(run.recording, run.rig, [effect_at_screened(c, s)], run.baseline.fit,
                                s.get("start_values"))
    except Exception as exc:  # noqa: BLE001 - a failed refit is reported in the result
        if not is_solver_failure(exc):
            raise
        trial.refitted, trial.status, trial.seconds = True, f"refit failed: {exc}", time.perf_counter() - t0
        return
    cost1, _ = estimation_cost(fit1, run.noise)
    fit1, cost1, retried = retry_from_neutral(run, c, fit1, cost1)
    judge_refit(run, trial, eff, fit1, cost1, c.n_added, retried)
    trial.seconds = time.perf_counter() - t0
    run.refits[eff] = (fit1, c)
