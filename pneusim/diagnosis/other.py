"""``other``: what the vocabulary does not name, said plainly -- where, under which conditions, what it looks like.

When the model with every finding (the nominal model where there is none) still leaves a residual well above
the sensor noise, on the estimation part *and* on the held-out validation part, and no vocabulary effect passed
the keep test on top of it, something the vocabulary has no name for is missing.  The honest answer is then
``other``, never the vocabulary effect that came closest: :func:`other_finding` reports the episodes where that
residual is (:func:`.locate.episodes`), their operating conditions, the signature numbers of that residual
(:mod:`.signatures`), and the candidates that came closest with why each was rejected.

The estimation residual alone decides, without the continuity defects a fit that ended in the penalty form left
open: those count in the keep test's costs (:func:`.refits.estimation_cost`), but they say that the optimiser
stopped short, not that physics is missing (``docs/decisions/0031``).
"""

from __future__ import annotations

import math

from .locate import episodes, named_states
from .refits import estimation_cost
from .result import Finding
from .rules import CLEARLY_SHORT, FURTHER_SEARCH_RESIDUAL, MAX_CLOSEST, OTHER_RESIDUAL, validation_room

__all__ = ["other_finding", "unexplained", "above_noise", "closest_candidates"]


def unexplained(fit, noise: dict, floor_points: float) -> tuple[bool, float]:
    """Whether ``fit`` leaves physics unexplained: its estimation residuals (no defects) above
    :data:`~.rules.OTHER_RESIDUAL` times the noise and its validation error above :data:`~.rules.CLEARLY_SHORT`
    times the noise floor ``F``; and that residual's rms in noise units."""
    ratio = residual_ratio(fit, noise)
    short = not math.isfinite(fit.fit_percent) or 100.0 - fit.fit_percent > CLEARLY_SHORT * floor_points
    return ratio > OTHER_RESIDUAL and short, ratio


def above_noise(fit, noise: dict, floor_points: float) -> bool:
    """Whether ``fit`` (the one-effect-first search's findings) is still above noise with room for more: its
    estimation residuals (no defects) above :data:`~.rules.FURTHER_SEARCH_RESIDUAL` times the noise and its
    validation error above what a refit needs to pass the keep test (:func:`~.rules.validation_room`)."""
    room = validation_room(fit.fit_percent, floor_points) if math.isfinite(fit.fit_percent) else math.inf
    return residual_ratio(fit, noise) > FURTHER_SEARCH_RESIDUAL and room > 0


def residual_ratio(fit, noise: dict) -> float:
    """The rms of ``fit``'s estimation residuals (no defects) in noise units."""
    cost, count = estimation_cost(fit, noise, defects=False)
    return math.sqrt(cost / max(count, 1))


def _reason(status: str) -> str:
    """The last outcome a trial's status gives (what rejected it)."""
    parts = [p.strip() for p in status.split("; ") if p.strip()]
    return parts[-1] if parts else status


def closest_candidates(trials: dict, kept: list, limit: int = MAX_CLOSEST) -> list[dict]:
    """The vocabulary candidates that came closest and were not kept: those refitted first, best validation
    fit first, then the screened ones by score; ``[{"effect", "why_rejected", "fit_percent"}]``."""
    rejected = [t for t in trials.values() if t.effect not in kept and not t.kept]
    refitted = sorted((t for t in rejected if t.refitted and t.fit_percent is not None),
                      key=lambda t: -t.fit_percent if math.isfinite(t.fit_percent) else math.inf)
    screened = sorted((t for t in rejected if t not in refitted and math.isfinite(t.score)), key=lambda t: -t.score)
    out = []
    for t in (refitted + screened)[:max(0, limit)]:
        out.append({"effect": t.effect, "why_rejected": _reason(t.status),
                    "fit_percent": t.fit_percent if t.fit_percent is not None and math.isfinite(t.fit_percent)
                    else None})
    return out


def other_finding(run, final, duration_s: float,
                  search_ended: str = "no vocabulary effect passed the test on top of it") -> Finding | None:
    """The ``other`` finding where ``final`` (the fit with every finding, or the nominal fit) leaves physics
    unexplained (:func:`unexplained`) in mismatch windows; else None.  ``run.stages.locate`` and
    ``run.stages.signatures`` read that fit's residual; ``search_ended`` says why no more vocabulary effects
    were added."""
    short, ratio = unexplained(final, run.noise, run.baseline.floor)
    if not short:
        return None
    states = named_states(final)
    windows, _ = run.stages.locate(run.recording, final.rig, states, run.noise)
    if not windows:
        return None
    signatures = run.stages.signatures(run.recording, final.rig, states, states["velocity_m_per_s"])
    where = episodes(windows, duration_s)
    kept = [e.name for e in final.effects_]
    closest = closest_candidates(run.trials, kept)
    model = "the nominal model" + (f" with {', '.join(kept)}" if kept else "")
    text = "; ".join(f"{w.t_start_s:.1f}-{w.t_end_s:.1f} s on {', '.join((w.signal, *w.also_in))} ({w.condition})"
                     for w in where)
    nearest = "; ".join(f"{c['effect']}: {c['why_rejected']}" for c in closest) or "none screened"
    evidence = (f"something not in the vocabulary: {model} leaves a residual of {ratio:.1f} times the sensor noise "
                f"on the estimation part and a validation fit of {final.fit_percent:.2f} %, in {len(windows)} "
                f"window(s), here: {text}; {search_ended} (closest: {nearest})")
    return Finding(effect="other", evidence=evidence, parameters={}, fit_percent=final.fit_percent,
                   improvement_points=0.0, mismatch=where, closest=closest, signatures=signatures)
