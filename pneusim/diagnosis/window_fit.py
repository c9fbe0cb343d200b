"""A set of effects pre-fitted on the window, kept so that one more effect continues from it.

:func:`pneusim.fit.prefit_recording` runs the fit's pre-fit from given parameter values but from segment
states estimated anew from the data, and returns the parameters only.  Sets of effects are compared by where
their pre-fits end, and a set with one more effect pre-fitted that way may end *above* the set without it: the
trust region spends its evaluations re-fitting the states, and a comparison of two sets is then decided by how
far each got, not by what the effect explains.  :func:`window_fit` builds the same problem (the fit's own
:class:`~pneusim.fit.setup.FitSetup` on the window, its pre-fit's trust region, direct route) but continues from
an earlier :class:`WindowFit`: its parameters (the new effect at its starting values) and its segment states
(the states the new model adds from its equilibrium at each segment's start, as a warm refit starts them).
Where the new effect starts at a value that is the model without it, the continuation starts at the set's own
optimum and can only go down from there: what it gains is what the effect explains on the window.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..fit.initial import initial_starts
from ..fit.rules import SEGMENT_SAMPLES
from ..fit.setup import FitSetup
from ..fit.stages import prefit
from ..fit.trust_region import trust_region
from .rules import DEFECT_WEIGHT

__all__ = ["WindowFit", "window_fit"]


@dataclass
class WindowFit:
    """A pre-fit on the window: ``cost`` (residual sum of squares in noise units plus the continuity defects
    weighted as in the fit's penalty form, :data:`~.rules.DEFECT_WEIGHT`), ``n_residuals``,
    ``normalised_residual`` (the residuals' rms alone, noise units), ``estimates`` (the free parameters, SI),
    ``values`` (every parameter of the model), ``states`` (segment start states, SI, one row a segment),
    ``state_names``, ``samples`` and ``seconds``.

    Why the defects in the cost: a pre-fit closes the segments only approximately, and an effect with states of
    its own that no sensor measures (chamber temperatures, a spool, a supply volume) lowers the residuals by
    opening its states' defects, segment by segment: a freedom of tens of variables on a window, which the
    residuals alone would credit to the effect's one or two parameters."""

    cost: float
    n_residuals: int
    normalised_residual: float
    estimates: dict
    values: dict
    states: np.ndarray
    state_names: list
    samples: int
    seconds: float
    #: the sum of squares of the continuity defects (state-scaled), unweighted
    defects: float = 0.0

    def objective(self, weight: float) -> float:
        """The residual sum of squares plus the defects weighted ``weight`` (the pre-fit's own objective at its
        continuity weight)."""
        return self.normalised_residual ** 2 * self.n_residuals + weight ** 2 * self.defects


def _warm_states(pb, values: dict, recording, warm: WindowFit) -> np.ndarray:
    """Segment start states from ``warm``'s (same window, same segments); the states its model lacks from this
    model's equilibrium at each segment's start."""
    model = pb.model
    shared = [(i, warm.state_names.index(s)) for i, s in enumerate(model.state_names) if s in warm.state_names]
    x_lo, x_hi = pb.state_bounds()
    out = np.zeros((pb.n_segments, pb.n))
    for j, k in enumerate(pb.starts):
        old = warm.states[j]
        named = dict(zip(warm.state_names, old))
        x = model.initial_state(None, float(named["position_m"]), float(recording.valve_cmd_V[k]), params=values,
                                pressures_Pa=(float(named["pressure_a_Pa"]), float(named["pressure_b_Pa"])))
        for i, i_old in shared:
            x[i] = old[i_old]
        out[j] = np.clip(x, x_lo, x_hi)
    return out


def window_fit(run, effects: list, start: int, samples: int, evaluations: int, warm: WindowFit | None = None,
               start_values: dict | None = None) -> WindowFit:
    """Pre-fit ``effects`` on the ``samples`` estimation samples from sample ``start``: from ``warm`` (its
    parameters and states, the new effects' at their given values) or, without one, from the data sheet
    (``start_values`` for the parameters named there), at most ``evaluations`` trust-region evaluations of the
    fit's pre-fit, direct route.  Raises like :func:`pneusim.fit.prefit_recording`."""
    started = time.perf_counter()
    rec = run.recording
    n = rec.n_samples
    split = int(round(n * (1.0 - run.baseline.validation_fraction)))
    window = rec.slice(rec.time_s[start], None) if start > 0 else rec
    values = dict(start_values or {})
    if warm is not None:
        values = {**warm.values, **values}
    setup = FitSetup(window, run.rig, effects, None, (n - split) / (n - start), None, values, SEGMENT_SAMPLES)
    pb, lo, hi = setup.problem(min(setup.n_est, int(samples)), 1e-6, 2)
    try:
        p0 = pb.params_of(setup.theta_start)
        if warm is None:
            x0 = initial_starts(pb, setup.theta_start, window, pb.data.n_samples)
        else:
            x0 = _warm_states(pb, dict(zip(pb.model.param_names, p0)), window, warm)
        v0 = pb.join(setup.theta_start, x0)
        if warm is None:
            v, _, _ = prefit(pb, v0, lo, hi, second_route=False, max_evaluations=evaluations)
        else:   # from a continuous solution: continuity kept at the fit's own penalty weight
            v, _, _ = trust_region(pb, v0, lo, hi, max_evaluations=evaluations, defect_weight=DEFECT_WEIGHT)
        e = pb.evaluate(v, derivatives=True)
        if not e["ok"]:
            raise ValueError("the model could not be integrated at the pre-fit's end on the window")
        theta, states = pb.split(v)
        p = pb.params_of(theta)
    finally:
        pb.close()
    residuals, defects = float(np.dot(e["r"], e["r"])), float(np.dot(e["g"], e["g"]))
    n_res = int(e["r"].size)
    names = pb.model.param_names
    return WindowFit(residuals + DEFECT_WEIGHT ** 2 * defects, n_res, float(np.sqrt(residuals / max(n_res, 1))),
                     {name: float(p[names.index(name)]) for name in setup.free}, dict(zip(names, map(float, p))),
                     np.asarray(states, float), list(pb.model.state_names), int(pb.data.n_samples),
                     time.perf_counter() - started, defects)
