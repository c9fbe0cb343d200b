"""The candidates: every vocabulary effect's screened variants and look-alike families, and the screening that
ranks them around a fit's optimum.

**Candidates.** Each effect of the vocabulary (:data:`pneusim.model.effects.EFFECTS`) is screened from its
own starts (:meth:`~pneusim.model.effects.Effect.screening_starts`): each leakage path, each transport delay
of a scan, every other effect at a small value (nearly absent, so the screening starts where the nominal fit
ended) or, where no value equals the nominal model or a parameter moves the response non-linearly, from a
few.  Effects whose signatures look alike form a family (:data:`FAMILIES`: dead time and spool lag, the
friction and load laws, offset and dead band, the slow pneumatic effects): a few steps cannot tell them
apart, a whole refit can.

**Screening (ranking).** For one candidate the multiple-shooting problem of the fit is built with the effect
switched on, started at the fitted optimum (parameters and segment states), and a few trust-region steps are
taken on the estimation part's first :data:`~.rules.SCREEN_SAMPLES` samples (:func:`screen`).  The drop of
the noise-normalised residual sum of squares (continuity defects included as in the fit) is the candidate's
likelihood gain: a Lagrange-multiplier-like score of what switching the effect on can explain, in the units
of the sensor noise.  It is counted beyond what the same steps take without any candidate
(:func:`polished_costs`).  A transport delay has no gradient; it is scanned over fixed delays instead
(:mod:`.delay`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..fit.parameters import parameter_bounds, parameter_scale
from ..fit.shooting import FitData, ShootingProblem
from ..fit.trust_region import trust_region
from ..fit.warm_start import warm_states
from ..model import ActuatorModel, make_effect
from ..model.effects import EFFECTS, effect_class, families as effect_families
from .rules import DEFECT_WEIGHT, SCANNED_EVALUATIONS, SCREEN_EVALUATIONS, SCREEN_SAMPLES, is_solver_failure

__all__ = ["Candidate", "candidate_list", "FAMILIES", "family_of", "NEUTRAL", "neutral_effect", "SCANNED", "screen",
           "screen_evaluations", "polished_costs", "DEFECT_WEIGHT"]

#: effects whose screening starts away from the nominal model (each effect's ``scanned``): they get
#: :data:`~.rules.SCANNED_EVALUATIONS` trust-region evaluations (so do the starts with a ``start_scale``)
SCANNED = tuple(name for name, cls in EFFECTS.items() if cls.scanned)
#: the values at which each effect that has one is (nearly) absent, as the screening starts it (each
#: effect's ``neutral``): a refit that ends above the nominal estimation residual is fitted once more from
#: here (:func:`.refits.retry_from_neutral`).  Effects without such a value are not retried.
NEUTRAL = {name: dict(cls.neutral) for name, cls in EFFECTS.items() if cls.neutral is not None}
#: effects with look-alike signatures (each effect's ``family``, in registry order): when one leads the
#: screening, the others are refitted too
FAMILIES = tuple(members for members in effect_families().values() if members)


@dataclass
class Candidate:
    """A candidate effect: its vocabulary name, the effect to switch on and the parameters to free."""

    name: str
    label: str
    effect: object
    free: list = field(default_factory=list)
    #: nominal parameters multiplied by these factors at the start of the screening (and the refit
    #: starts from their screened values)
    start_scale: dict = field(default_factory=dict)

    @property
    def n_added(self) -> int:
        """Parameters the effect adds for the information criterion (its ``added_parameters``)."""
        return type(self.effect).added_parameters(self.free)


def candidate_list(rig, sample_time_s: float, names=None, delays_s=None) -> list[Candidate]:
    """The screened variants of every vocabulary effect (``names``: restrict to these effects;
    ``delays_s``: the transport delays to scan, default the transport delay's own scan), in registry
    order: each effect's :meth:`~pneusim.model.effects.Effect.screening_starts`, with its ``fit_free``
    parameters but those searched by a grid.  An unknown name is refused (one sentence naming it)."""
    names = list(EFFECTS) if names is None else list(names)
    classes = [effect_class(name) for name in names]   # an unknown name is refused before any work
    out = []
    for name, cls in zip(names, classes):
        free = [f"{name}.{key}" for key in cls.fit_free if key not in cls.searched]
        for start in cls.screening_starts(rig.params, sample_time_s, delays_s):
            out.append(Candidate(name, start.label, start.effect, list(free), dict(start.start_scale)))
    return out


def family_of(effect: str) -> tuple:
    """The look-alike family of ``effect``: the effects of its class's ``family`` (:data:`FAMILIES`), itself
    alone when it is not a vocabulary effect."""
    cls = EFFECTS.get(effect)
    return effect_families()[cls.family] if cls is not None else (effect,)


def neutral_effect(candidate: Candidate):
    """``candidate``'s effect at its neutral values (the effect's ``neutral``, :data:`NEUTRAL`; options
    kept), or None when it has none."""
    effect = candidate.effect
    values = type(effect).neutral
    if values is None:
        return None
    return make_effect(candidate.name, **effect.option_values, **{**effect.values, **values})


# --------------------------------------------------------------------------------------- screening
def _problem(fit, recording, effects, free_extra, noise, samples, start_scale=None):
    """The shooting problem of ``fit``'s nominal free parameters plus ``free_extra`` with ``effects`` on,
    over the first ``samples`` estimation samples, started at the fit's optimum (with the parameters
    in ``start_scale`` multiplied by their factors)."""
    rig = fit.rig
    model = ActuatorModel(effects)
    p_data_sheet = model.param_vector(rig)
    p = p_data_sheet.copy()
    fitted = dict(zip(fit.model.param_names, np.asarray(fit.params_vector, float)))
    for i, name in enumerate(model.param_names):
        if name in fitted:
            p[i] = fitted[name]
        p[i] *= (start_scale or {}).get(name, 1.0)
    free = [n for n in fit.free if n in model.param_names] + [n for n in free_extra if n not in fit.free]
    index = [model.param_names.index(n) for n in free]
    scales = np.array([parameter_scale(n, p_data_sheet[i]) for n, i in zip(free, index)])
    bounds = np.array([parameter_bounds(n, p_data_sheet[i]) for n, i in zip(free, index)])
    lower, upper = bounds[:, 0] / scales, bounds[:, 1] / scales
    theta = np.clip(p[index] / scales, lower, upper)
    stop = int(samples)
    signals = {"position_m": (recording.position_m[:stop], noise["position_m"])}
    if recording.has_pressures:
        for name in ("pressure_a_Pa", "pressure_b_Pa"):
            signals[name] = (getattr(recording, name)[:stop], noise[name])
    data = FitData(recording.time_s[:stop], recording.valve_cmd_V[:stop], float(recording.valve_cmd_V[0]), signals)
    seg = int(fit.solver.get("segment_samples", 50))
    pb = ShootingProblem(model, p, free, scales, data, rig.stroke_m, seg, model.command_delay_s(), 1e-6, 2)
    x_lo, x_hi = pb.state_bounds()
    lo = np.concatenate([lower, np.tile(x_lo / pb.x_scale, pb.n_segments)])
    hi = np.concatenate([upper, np.tile(x_hi / pb.x_scale, pb.n_segments)])
    v0 = pb.join(theta, warm_states(fit, pb, p, recording))
    return pb, v0, lo, hi, free


def _total_cost(pb, v) -> float:
    """The trust region's objective at ``v`` (residuals, defects weighted by :data:`~.rules.DEFECT_WEIGHT`),
    integrated with sensitivities as :func:`~pneusim.fit.trust_region.trust_region` integrates every point: the
    state's own memory steps differently, and on a chaotic stick-slip window the two costs of one point differ
    by several percent (``docs/decisions/0030``), more than a small candidate's gain."""
    e = pb.evaluate(v, derivatives=True)
    if not e["ok"]:
        return float("inf")
    return float(np.dot(e["r"], e["r"]) + DEFECT_WEIGHT ** 2 * np.dot(e["g"], e["g"]))


def screen(fit, recording, candidate: Candidate | None, noise: dict, samples: int | None = None,
           evaluations: int = SCREEN_EVALUATIONS) -> dict:
    """Screen one candidate (``None``: ``fit``'s own model, evaluated only) on top of ``fit``: its
    effects (none for the nominal fit) stay switched on at their fitted values.

    Returns ``{"cost": C after the steps, "cost_start": C at the start, "parameters": {...}, "seconds"}``
    and, for a candidate with a ``start_scale``, ``"start_values"``: the screened values of those
    nominal parameters (the refit starts there).
    """
    started = time.perf_counter()
    stop = min(fit.n_estimation, samples or SCREEN_SAMPLES)
    effects = list(fit.effects_) + ([] if candidate is None else [candidate.effect])
    extra = [] if candidate is None else candidate.free
    pb, v0, lo, hi, free = _problem(fit, recording, effects, extra, noise, stop,
                                    None if candidate is None else candidate.start_scale)
    try:
        cost_start = _total_cost(pb, v0)
        if candidate is None or evaluations <= 0:
            return {"cost": cost_start, "cost_start": cost_start, "parameters": {},
                    "seconds": time.perf_counter() - started}
        evaluations = screen_evaluations(candidate, evaluations)
        v, _, info = trust_region(pb, v0, lo, hi, max_evaluations=evaluations, defect_weight=DEFECT_WEIGHT)
        cost = _total_cost(pb, v)
        theta, _ = pb.split(v)
        p = pb.params_of(theta)
        params = {n: float(p[pb.model.param_names.index(n)]) for n in candidate.free}
        out = {"cost": cost, "cost_start": cost_start, "parameters": params, "seconds": time.perf_counter() - started}
        if candidate.start_scale:
            out["start_values"] = {n: float(p[pb.model.param_names.index(n)]) for n in candidate.start_scale}
        return out
    finally:
        pb.close()


def screen_evaluations(candidate: Candidate, evaluations: int = SCREEN_EVALUATIONS) -> int:
    """Trust-region evaluations :func:`screen` gives ``candidate``: more for a scanned effect or one that
    moves nominal parameters (:data:`~.rules.SCANNED_EVALUATIONS`)."""
    if type(candidate.effect).scanned or candidate.start_scale:
        return max(evaluations, SCANNED_EVALUATIONS)
    return evaluations


def polished_costs(fit, recording, noise: dict, samples: int | None = None,
                   evaluations=(SCREEN_EVALUATIONS, SCANNED_EVALUATIONS)) -> dict:
    """What the screening's trust-region steps take with no candidate: ``{evaluations: cost}``, the cost on
    the screening window after that many steps of ``fit``'s own free parameters and shooting states.
    Around the nominal optimum a candidate's gain is measured from here, so that it counts what the effect
    explains, not what the same steps find anyway.

    Why: ``fit`` is optimal on its whole estimation part, not on the window's first samples, and a few steps
    there gain alike with any candidate: on a control, every candidate's gain was the steps' own, and each
    was refitted for nothing (``docs/decisions/0030``).  On a solver failure the cost stays where the steps
    start."""
    stop = min(fit.n_estimation, samples or SCREEN_SAMPLES)
    pb, v0, lo, hi, _ = _problem(fit, recording, list(fit.effects_), [], noise, stop)
    try:
        start = _total_cost(pb, v0)
        out = {}
        for n in sorted(set(evaluations)):
            try:
                v, _, _ = trust_region(pb, v0, lo, hi, max_evaluations=n, defect_weight=DEFECT_WEIGHT)
                out[n] = min(start, _total_cost(pb, v))
            except Exception as exc:  # noqa: BLE001 - the steps may fail to integrate: no polish then
                if not is_solver_failure(exc):
                    raise
                out[n] = start
        return out
    finally:
        pb.close()
