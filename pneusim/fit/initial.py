"""Initial guesses of the segment start states for the shooting problem."""

from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

from ..errors import PneusimError
from ..recording import Recording
from .rules import (FIRST_STATE_EVALUATIONS, FIRST_STATE_GRID_POINTS, FIRST_STATE_LOCAL_STARTS,
                    FIRST_STATE_PRIOR_WIDTH, START_VELOCITY_SMOOTHING_S)
from .shooting import ShootingProblem

__all__ = ["initial_starts", "better_first_state"]


def initial_starts(pb: ShootingProblem, theta0, recording: Recording, stop: int,
                   choose_starts: bool = False) -> np.ndarray:
    """Segment start states: the measured states (position, pressures when recorded) from the
    measurement; the others estimated from the first segment's samples at the start, then carried
    over from a simulation of the previous segment at ``theta0`` (a velocity from differentiated
    noisy positions would be a worse guess than the simulated one).

    With ``choose_starts`` and both chamber pressures recorded, a segment after the first starts from
    whichever of two states fits its own samples better at ``theta0``: the measured state or the state
    carried over from the previous segment's simulation unchanged.  Why: a pressure sample is off by its
    sensor noise, and in a nearly empty chamber (piston near its stop) that error starts a spurious
    stick-slip the fit cannot leave: on a paper-2 open-loop recording at its true parameters the measured
    starts put two segments at 5.2 and 2.9 times noise and the whole part at 1.08 after the trust region;
    with the choice it ends at 0.994, as from the true states.  Only where the parameters are already
    close (:data:`~pneusim.fit.stages.SHORT_SEGMENTS`' route): from the data sheet, and without pressures,
    the carried state drifts off the samples (two paper-1 recordings without pressures went from noise
    to 1.34 and 1.90 times it)."""
    ts = recording.sample_time_s
    width = max(5, int(round(START_VELOCITY_SMOOTHING_S / ts)) | 1)
    velocity = savgol_filter(recording.position_m[:stop], min(width, stop - (1 - stop % 2)), 2, deriv=1, delta=ts)
    params = pb.params_of(theta0)
    model = pb.model
    x = model.initial_state(None, float(recording.position_m[0]),
                            float(recording.valve_cmd_V[0]), params=dict(zip(model.param_names, params)))
    pb.sims[0].set_params(params)
    starts = np.zeros((pb.n_segments, pb.n))
    measured = {name: values for name, (values, _) in pb.data.signals.items()}
    choose = choose_starts and {"pressure_a_Pa", "pressure_b_Pa"} <= set(measured)
    x_lo, x_hi = pb.state_bounds()
    for j, k in enumerate(pb.starts):
        x = np.clip(x, x_lo, x_hi)
        if j == 0:
            x[1] = velocity[k]
        carried = x.copy()
        for name, values in measured.items():
            if np.isfinite(values[k]):
                x[model.state_names.index(name)] = values[k]
        if j == 0:
            x = _hidden_state(pb, j, x, params, grid=True)
        candidates = [x, carried] if choose and j > 0 else [x]
        starts[j], xs = _best_start(pb, j, candidates)
        x = xs[-1] if xs is not None else starts[j]
    return starts


def _best_start(pb: ShootingProblem, j: int, candidates):
    """``(state, states)``: of candidate start states of segment ``j``, the first whose simulation by
    ``pb.sims[0]`` (at the parameters last set on it) fits the segment's samples best, and that
    simulation (None where it failed)."""
    best = None
    for candidate in candidates:
        try:
            xs, _ = pb.sims[0].run(pb.data.time_s[pb.starts[j]], candidate, pb.schedules[j],
                                   pb.stops[j] - pb.starts[j] + 1, False)
        except PneusimError:
            xs = None
        cost = _cost(pb, j, xs)
        if best is None or cost < best[0]:
            best = (cost, candidate, xs)
    return best[1], best[2]


def _segment_residuals(pb: ShootingProblem, j: int, x: np.ndarray, sensitivities: bool = False, sim=None):
    """``(r, J)``: the normalised residuals of segment ``j``'s samples simulated from the start state
    ``x`` by ``sim`` (default ``pb.sims[0]``; at the parameters last set on it), and with ``sensitivities`` their
    Jacobian over all of that simulator's sensitivity columns (else None).  A missing sample gives a
    zero residual.  Raises :class:`PneusimError` where the integration fails."""
    first, n_out = pb.starts[j], pb.stops[j] - pb.starts[j] + 1
    xs, S = (sim or pb.sims[0]).run(pb.data.time_s[first], np.asarray(x, float), pb.schedules[j], n_out,
                                    sensitivities)
    r = _residuals(pb, j, xs)
    if not sensitivities:
        return r, None
    return r, np.concatenate([np.nan_to_num(S[:, pb.model.state_names.index(name), :] / s
                                            * np.isfinite(values[first:first + n_out])[:, None])
                              for name, (values, s) in pb.data.signals.items()])


def _residuals(pb: ShootingProblem, j: int, xs: np.ndarray) -> np.ndarray:
    """The normalised residuals of segment ``j``'s samples against its simulated states ``xs`` (one row a
    sample from the segment's start); a missing sample gives a zero residual."""
    first, n_out = pb.starts[j], xs.shape[0]
    return np.concatenate([np.nan_to_num((xs[:, pb.model.state_names.index(name)] - values[first:first + n_out]) / s)
                           for name, (values, s) in pb.data.signals.items()])


def _cost(pb: ShootingProblem, j: int, xs) -> float:
    """Residual sum of squares of segment ``j`` (:func:`_residuals`); inf where it could not be simulated."""
    if xs is None:
        return np.inf
    r = _residuals(pb, j, xs)
    return float(np.dot(r, r))


def better_first_state(pb: ShootingProblem, theta, states) -> np.ndarray:
    """Of candidate start states of the first segment, the one whose simulation at the parameters
    ``theta`` fits that segment's samples best (normalised residual sum of squares).

    Why: the first state is estimated at the starting parameters, tens of percent off, and a
    recording that starts mid stick-slip has one basin per slip pattern; the pre-fit only moves
    locally from its start (paper 2, open-loop steps without pressures: a start velocity of
    -0.37 m/s against -0.087 true, residuals of 20-27 times noise on the first ten samples and 2.06
    times noise over the whole fit).  The fitter offers the pre-fit's own first state and one
    estimated afresh at the pre-fit's parameters."""
    pb.sims[0].set_params(pb.params_of(theta))
    return np.asarray(_best_start(pb, 0, [np.asarray(x, float) for x in states])[0], float).copy()


def _hidden_state(pb: ShootingProblem, j: int, x0: np.ndarray, params: np.ndarray, grid: bool) -> np.ndarray:
    """The velocity and unmeasured chamber pressures at the start of segment ``j`` that best explain
    its samples: from ``x0`` (and, with ``grid``, a coarse grid of pressures), trust-region least
    squares on the segment's residuals with the parameters fixed.

    A recording starts wherever the rig was: with a closed-centre valve near null the chamber
    pressures can be anything the friction holds, so they are estimated, not assumed.  When the
    piston rests, its samples say nothing about them; a broad prior around ``x0`` (the smoothed
    velocity, pressures that balance the piston) then keeps the estimate physical, and it is
    between the exhaust and the supply pressure.
    """
    from scipy.optimize import least_squares

    model = pb.model
    for sim in pb.sims:
        sim.set_params(params)
    names = ["velocity_m_per_s"] + [s for s in ("pressure_a_Pa", "pressure_b_Pa") if s not in pb.data.signals]
    hidden = [model.state_names.index(s) for s in names]
    value = dict(zip(model.param_names, params))
    low = min(value["exhaust_Pa"], value["atmosphere_Pa"])
    high = value["supply_Pa"]
    x_lo, x_hi = pb.state_bounds()
    x_lo[2:4], x_hi[2:4] = low, high
    z_lo, z_hi = x_lo[hidden] / pb.x_scale[hidden], x_hi[hidden] / pb.x_scale[hidden]
    z_prior = np.clip(x0[hidden] / pb.x_scale[hidden], z_lo, z_hi)
    prior_width = np.array([FIRST_STATE_PRIOR_WIDTH[n] for n in names]) / pb.x_scale[hidden]
    n_res = (pb.stops[j] - pb.starts[j] + 1) * len(pb.data.signals) + len(hidden)
    cols = [pb.n_free + i for i in hidden]

    def residuals(sim, z, jac=False):
        x = x0.copy()
        x[hidden] = z * pb.x_scale[hidden]
        try:
            r, J = _segment_residuals(pb, j, x, jac, sim)
        except PneusimError:
            return (np.full(n_res, 1e6), np.zeros((n_res, len(hidden)))) if jac else np.full(n_res, 1e6)
        r = np.concatenate([r, (z - z_prior) / prior_width])
        if not jac:
            return r
        return r, np.vstack([J[:, cols], np.diag(1.0 / prior_width)])

    def cost(sim, z):
        r = residuals(sim, z)
        return float(np.dot(r, r))

    def refine(sim, z):
        fit = least_squares(lambda z: residuals(sim, z), np.clip(z, z_lo, z_hi),
                            jac=lambda z: residuals(sim, z, True)[1], method="trf", bounds=(z_lo, z_hi),
                            max_nfev=FIRST_STATE_EVALUATIONS)
        return fit.x, cost(sim, fit.x)

    candidates = [z_prior]
    grid = np.linspace(low, high, FIRST_STATE_GRID_POINTS + 2)[1:-1] if (grid and len(hidden) > 1) else []
    for pa in grid:
        for pb_ in (grid if len(hidden) > 2 else [None]):
            z = z_prior.copy()
            z[1] = pa / pb.x_scale[hidden[1]]
            if pb_ is not None:
                z[2] = pb_ / pb.x_scale[hidden[2]]
            candidates.append(z)
    # the grid's points and the local refinements are independent: spread over the problem's simulators
    costs = pb.map_sims(cost, candidates)
    best_z, best_cost = candidates[int(np.argmin(costs))], min(costs)
    for z, c in pb.map_sims(refine, [candidates[i] for i in np.argsort(costs)[:FIRST_STATE_LOCAL_STARTS]]):
        if c < best_cost:
            best_z, best_cost = z, c
    x = x0.copy()
    x[hidden] = np.clip(best_z, z_lo, z_hi) * pb.x_scale[hidden]
    return x
