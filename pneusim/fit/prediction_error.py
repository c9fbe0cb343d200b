"""The prediction-error fit: free parameters (and the first state) that minimise the innovations of an
extended Kalman filter over a window, the one-step-ahead predictor of :mod:`.tracking`.

Why: a recording whose piston stick-slips from sample to sample (paper 2 in open loop, paper 1's
closed-loop multisine without pressures) is chaotic on the fit's time scale.  The shooting problem's
residual then depends on the phase of every slip, and its landscape in the friction parameters is
rippled by every mistimed micro-slip: from the data sheet's values the pre-fit stops in a wrong basin,
whatever the starts.  The filter corrects the state after every sample, so its innovations depend
smoothly on the parameters: along the line from a chaotic recording's data-sheet values to its truth
the filter's negative log-likelihood falls monotonically to its minimum at the truth, where the shooting
residual does not.  Far from the truth the filter can still lose track of the piston, and where it does
depends on the integrator's rounding (``docs/decisions/0018``).

The process noise is what smooths the landscape and what lets the filter absorb a wrong model: the fit
lowers it in turn (:data:`~.rules.PROCESS_SCHEDULE`), each stage from the last one's point, a homotopy from
a broad basin to the sharp minimum.  Chamber pressures that the recording does not measure get a fraction
of the others' process noise (:data:`~.rules.PRESSURE_FACTOR`): a filter free to move them explains a wrong
valve and friction by them.  Measured pressures keep theirs: the measurements hold them, and a filter
that cannot follow them loses track of the piston at the data sheet's values.  The friction smoothing
velocity is held in the broad stages (:data:`~.rules.HELD_BROAD`): a broad filter trades it for mistimed
slips.

The gradient holds the filter's gain fixed (the state sensitivities propagate through the model's
one-sample sensitivities and ``I - K H``); the least squares are SciPy's trust region on the whitened
innovations with that Jacobian.
"""
from __future__ import annotations

import time

import numpy as np
from scipy.optimize import least_squares

from .parameters import clip_inside
from .rules import (HELD_BROAD, HELD_UNTIL, PREDICTION_ERROR_EVALUATIONS,
                    PREDICTION_ERROR_TOLERANCE, PRESSURE_FACTOR, PROCESS_SCHEDULE, SAME_PREFIT)
from .shooting import ShootingProblem
from .tracking import process_std, run_filter

__all__ = ["prediction_error_fit", "prediction_error_attempts", "PROCESS_SCHEDULE", "PRESSURE_FACTOR"]


def prediction_error_fit(pb: ShootingProblem, theta0: np.ndarray, x_first: np.ndarray, lower: np.ndarray,
                         upper: np.ndarray, schedule=PROCESS_SCHEDULE, give_up_above: float = np.inf):
    """Least squares on the filter's whitened innovations over ``pb``'s window, from the scaled free
    parameters ``theta0`` and the first state ``x_first`` (SI), ``theta`` within ``lower .. upper``, the first
    state within :meth:`ShootingProblem.state_bounds`; one stage per process noise of ``schedule``, stopped
    after a stage that ends above ``give_up_above``.

    Why that stop: with less process noise the filter corrects less, and the innovations of a model that
    lacks physics only grow stage by stage, where those of a chaotic recording the model explains approach
    their noise level (``docs/decisions/0018``).

    Returns ``(theta, x_first, info)``: the scaled parameters and first state (SI) of the last stage, and
    ``info`` with each stage's process noise, rms of the whitened innovations (1 where the model is right
    and the filter well tuned), passes and seconds, and the last stage's rms as ``"rms_innovations"``.
    """
    nf, n = pb.n_free, pb.n
    x_lo, x_hi = pb.state_bounds()
    lo = np.concatenate([lower, x_lo / pb.x_scale])
    hi = np.concatenate([upper, x_hi / pb.x_scale])
    w = clip_inside(np.concatenate([theta0, np.asarray(x_first, float) / pb.x_scale]), lo, hi)
    n_seen = max(1, sum(int(mask.sum()) for (_, _, _, _, mask) in pb.outputs))   # a gap's innovation is 0
    stages = []
    for fraction in schedule:
        process = process_std(pb, fraction, PRESSURE_FACTOR)
        cache = {}

        def evaluate(v):
            key = v.tobytes()
            if key not in cache:
                cache.clear()
                run = run_filter(pb, v[:nf], v[nf:] * pb.x_scale, process, gradients=True)
                if not run["ok"]:
                    # a point the model cannot be integrated at: no finite cost, the trust region shrinks
                    run["innovations"] = np.full_like(run["innovations"], np.inf)
                cache[key] = run
            return cache[key]

        started = time.perf_counter()
        if not np.all(np.isfinite(evaluate(w)["innovations"])):
            # the filter cannot run from this point at all: nothing to fit
            stages.append({"process_std": fraction, "rms_innovations": float("inf"), "evaluations": 1,
                           "seconds": time.perf_counter() - started})
            break
        # the variables this stage moves: all but the held parameters in the broad stages
        moving = np.array([not (name in HELD_BROAD and fraction > HELD_UNTIL) for name in pb.free] + [True] * n)
        base = w.copy()

        def full(u):
            v = base.copy()
            v[moving] = u
            return v

        fit = least_squares(lambda u: evaluate(full(u))["innovations"], w[moving],
                            jac=lambda u: evaluate(full(u))["jacobian"][:, moving],
                            bounds=(lo[moving], hi[moving]), method="trf", x_scale=1.0,
                            max_nfev=PREDICTION_ERROR_EVALUATIONS, xtol=PREDICTION_ERROR_TOLERANCE,
                            ftol=PREDICTION_ERROR_TOLERANCE)
        w = full(fit.x)
        rms = float(np.sqrt(np.sum(fit.fun ** 2) / n_seen)) if np.all(np.isfinite(fit.fun)) else float("inf")
        stages.append({"process_std": fraction, "rms_innovations": rms, "evaluations": int(fit.nfev),
                       "seconds": time.perf_counter() - started})
        if not rms <= give_up_above:
            break
    info = {"stages": stages, "rms_innovations": stages[-1]["rms_innovations"],
            "seconds": sum(s["seconds"] for s in stages)}
    return w[:nf], w[nf:] * pb.x_scale, info


def prediction_error_attempts(pb: ShootingProblem, starts, x_first: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                              give_up_above: float = np.inf, schedule=PROCESS_SCHEDULE) -> list:
    """The prediction-error fit from several starts of the same parameters, the lowest end confirmed: ``starts``
    (scaled parameter vectors, the first the start itself, the others nearby; ``x_first`` the first state, SI).

    From the first start the whole ``schedule`` (:func:`prediction_error_fit`).  Unless its first stage ended above
    ``give_up_above`` (a model that lacks physics, which no start supplies): the first, broadest stage from each
    other start, then the rest of the schedule from those landings in the order of their innovations, lowest
    first, until a start ends within :data:`~.rules.SAME_PREFIT` (relative) of the lowest end so far (two starts
    agree on the lowest basin found), or every start has been continued.

    Why not stop at the first start that ends at the innovations' noise level: on a chaotic recording a start can
    end at the noise level in a wrong basin (whitened innovations 0.956, where the truth's basin gives 0.767 and
    the whole fit then reaches the noise with five of seven parameters beyond 3 standard errors), and which start
    does is a draw of the last bits of the arithmetic.  The lowest end, once a second start confirms it, is the
    same on every machine (``docs/decisions/0103``).
    """
    theta, first, info = prediction_error_fit(pb, starts[0], x_first, lower, upper, schedule, give_up_above)
    out = [(theta, first, {**info, "start": 0})]
    if not info["stages"][0]["rms_innovations"] <= give_up_above or len(starts) == 1:
        return out
    landings = [(k, *prediction_error_fit(pb, start, x_first, lower, upper, schedule[:1], give_up_above))
                for k, start in enumerate(starts[1:], 1)]
    lowest, order = info["rms_innovations"], sorted(landings, key=lambda landing: (landing[3]["rms_innovations"],
                                                                                   landing[0]))
    for n, (k, theta, first, landed) in enumerate(order):
        if not landed["rms_innovations"] <= give_up_above:
            out += [(None, None, {**rest[3], "start": rest[0]}) for rest in order[n:]]
            break
        theta, first, rest = prediction_error_fit(pb, theta, first, lower, upper, schedule[1:], give_up_above)
        out.append((theta, first, {"stages": landed["stages"] + rest["stages"], "start": k,
                                   "rms_innovations": rest["rms_innovations"],
                                   "seconds": landed["seconds"] + rest["seconds"]}))
        if abs(rest["rms_innovations"] / lowest - 1.0) < SAME_PREFIT:
            out += [(None, None, {**later[3], "start": later[0]}) for later in order[n + 1:]]
            break
        lowest = min(lowest, rest["rms_innovations"])
    return out
