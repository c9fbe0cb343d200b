"""Segment start states tracked through a recording by an extended Kalman filter at given parameters.

Why: a segment's start state carried over from a simulation of the segments before it is useless on
a recording whose piston stick-slips from sample to sample (paper 2 in open loop).  There the model is
chaotic on the fit's time scale: even at the *true* parameters, segments started from the chained
simulation fit their first samples at the noise level and leave the recorded slip pattern within
seconds.  Searching each segment's hidden states afresh on a grid (:func:`.initial._hidden_state`) brings
them back at a cost of seconds per segment; filtering the whole window once, sample by sample, with the
position (and pressures) correcting the model's state after every step, does the same for the cost of
one integration.  The filter only helps near the truth: at the data sheet's parameters (tens of percent
off) its starts fit no better than the chained ones, so the fitter uses it after a fit, from that fit's
parameters (:func:`.rescue_routes.tracked_route`; ``docs/decisions/0017``).

The filter's update is the extended Kalman filter's in Joseph form (filterpy's equations, written for
measurements that read states directly); its prediction is one sample of the fit's own integrator
(:class:`~pneusim.solver.sensitivity.SensitivitySimulator`, the held command and any transport delay as in the
fit), linearised by that integrator's state sensitivities.  The same filter
(:func:`run_filter`) gives the prediction-error fit (:mod:`.prediction_error`) its whitened innovations and
their fixed-gain Jacobian.
"""

from __future__ import annotations

import numpy as np

from ..errors import PneusimError
from ..solver.backends import state_scales
from ..solver.sensitivity import command_schedule
from .rules import FIRST_STATE_STD, PROCESS_STD
from .shooting import ShootingProblem, expected_position_reading

__all__ = ["filtered_states", "run_filter", "process_std", "first_state_std", "PROCESS_STD"]


def filtered_states(pb: ShootingProblem, theta: np.ndarray, x_first: np.ndarray) -> np.ndarray:
    """Filtered states ``(N, n)`` at every sample of ``pb``'s window, at the scaled free parameters
    ``theta``, from the first state ``x_first`` (SI).

    Each step integrates one sample from the filtered state with state sensitivities (the transition
    Jacobian), and the measured signals of that sample update it (the position through the saturating
    sensor's mean reading, :func:`.shooting.expected_position_reading`; a missing sample is skipped).
    A step the integrator cannot take keeps the state as it was.  States stay within
    :meth:`ShootingProblem.state_bounds`.
    """
    return run_filter(pb, theta, x_first, process_std(pb))["states"]


def process_std(pb: ShootingProblem, fraction: float = PROCESS_STD,
                unmeasured_pressure_factor: float = 1.0) -> np.ndarray:
    """Process noise std per sample and state (SI): ``fraction`` of each state's typical magnitude, the
    position's 1e-3 of that (the model integrates it from the velocity), and the chamber pressures'
    ``unmeasured_pressure_factor`` of that where the window does not measure them."""
    scales = state_scales(pb.model, pb.stroke_m)
    out = fraction * scales
    out[pb.position_index] *= 1e-3
    measured = {name for (_, name, _, _, _) in pb.outputs}
    for i, name in enumerate(pb.model.state_names):
        if name in ("pressure_a_Pa", "pressure_b_Pa") and name not in measured:
            out[i] *= unmeasured_pressure_factor
    return out


def first_state_std(pb: ShootingProblem) -> np.ndarray:
    """Prior std of the first state (SI): :data:`.rules.FIRST_STATE_STD`, else 1 % of the state's typical magnitude."""
    scales = state_scales(pb.model, pb.stroke_m)
    return np.array([FIRST_STATE_STD.get(name, 0.01 * s) for name, s in zip(pb.model.state_names, scales)])


def run_filter(pb: ShootingProblem, theta: np.ndarray, x_first: np.ndarray, process: np.ndarray,
               gradients: bool = False) -> dict:
    """The extended Kalman filter over ``pb``'s window at the scaled free parameters ``theta`` from the first
    state ``x_first`` (SI), with process noise std ``process`` (SI, per state and sample).

    Returns ``{"states": (N, n) filtered states, "ok": whether every step integrated}``; with ``gradients``
    also ``"innovations"``: the whitened innovations ``L_k^-1 (y_k - h(x_k^-))`` of every measured value
    (``S_k = L_k L_k^T`` their predicted covariance; a missing value gives 0), and ``"jacobian"``: their
    derivative with respect to ``(theta, x_first / pb.x_scale)``, the gain held fixed (the usual
    prediction-error gradient: the state sensitivities propagate through the model's one-sample
    sensitivities and the update's ``I - K H``), shape ``(N * n_measured, n_free + n)``.
    """
    sim, data = pb.sims[0], pb.data
    n, nf = pb.n, pb.n_free
    sim.set_params(pb.params_of(theta))
    rows = np.array([i for (i, _, _, _, _) in pb.outputs])
    values = np.column_stack([values for (_, _, values, _, _) in pb.outputs])
    sigma = np.array([sigma for (_, _, _, sigma, _) in pb.outputs])
    seen_at = np.column_stack([mask for (_, _, _, _, mask) in pb.outputs])
    state = {"x": np.asarray(x_first, float).copy(), "P": np.diag(first_state_std(pb) ** 2), "Z": None}
    Q = np.diag(np.asarray(process, float) ** 2)
    x_lo, x_hi = pb.state_bounds()
    out = np.empty((data.n_samples, n))
    ok = True
    if gradients:
        innovations = np.zeros((data.n_samples, rows.size))
        jacobian = np.zeros((data.n_samples, rows.size, nf + n))
        state["Z"] = np.zeros((n, nf + n))   # d x / d (theta, x_first scaled)
        state["Z"][:, nf:] = np.diag(pb.x_scale)
    for k in range(data.n_samples):
        if k > 0:
            schedule = command_schedule(data.time_s, data.command_V, k - 1, k, pb.delay_s, data.command_before_V)
            try:
                xs, S = sim.run(data.time_s[k - 1], state["x"], schedule, 2, True)
            except PneusimError:
                xs = None
            if xs is not None and np.all(np.isfinite(xs[1])):
                F = S[1][:, nf:nf + n] / pb.x_scale[None, :]     # d x_k / d x_{k-1}: the columns are scaled
                state["x"] = xs[1]
                state["P"] = F @ state["P"] @ F.T + Q
                if gradients:
                    state["Z"] = F @ state["Z"]
                    state["Z"][:, :nf] += S[1][:, :nf]
            else:
                ok = False
        seen = seen_at[k]
        if seen.any():
            whitened, slopes = _update(pb, state, rows[seen], values[k, seen], sigma[seen])
            if gradients:
                innovations[k, seen], jacobian[k, seen] = whitened, slopes
        state["x"] = np.clip(state["x"], x_lo, x_hi)
        out[k] = state["x"]
    result = {"states": out, "ok": ok}
    if gradients:
        result["innovations"] = innovations.ravel()
        result["jacobian"] = jacobian.reshape(-1, nf + n)
    return result


def _update(pb: ShootingProblem, state: dict, at: np.ndarray, measured: np.ndarray, sigma: np.ndarray):
    """The filter's measurement update of ``state`` (``x``, ``P`` and, unless None, the sensitivities ``Z``) by
    the values ``measured`` of states ``at`` (noise std ``sigma``): ``(whitened innovations, their derivative)``
    (the derivative None without ``Z``).

    The extended Kalman filter's update in Joseph form, ``P = (I - K H) P (I - K H)^T + K R K^T`` (filterpy's),
    written for measurements that read states directly: each measured value is one state (the position through
    the saturating sensor's mean reading, :func:`.shooting.expected_position_reading`), so ``H`` is a scaled
    selection of rows and ``P H^T`` a scaled selection of columns, and one value makes the innovation's
    covariance a number.  Why not filterpy's object: its bookkeeping of general matrices took a third of a
    prediction-error fit's time (``docs/decisions/0101``).
    """
    x, P, Z = state["x"], state["P"], state["Z"]
    # the model's readings and their slopes at the predicted state: H = diag(slope) E_at
    reading, slope = x[at].copy(), np.ones(at.size)
    p = np.flatnonzero(at == pb.position_index)
    if p.size:
        reading[p[0]], slope[p[0]] = expected_position_reading(x[pb.position_index], pb.stroke_m, sigma[p[0]])
    PHT = P[:, at] * slope                                       # P H^T
    S = PHT[at] * slope[:, None] + np.diag(sigma ** 2)           # H P H^T + R
    y = measured - reading
    if at.size == 1:
        L = np.sqrt(S)
        K = PHT / S[0, 0]
    else:
        L = np.linalg.cholesky(S)
        K = np.linalg.solve(S, PHT.T).T                          # P H^T S^-1
    I_KH = np.eye(x.size)
    I_KH[:, at] -= K * slope                                     # I - K H
    state["x"] = x + K @ y
    state["P"] = I_KH @ P @ I_KH.T + (K * sigma ** 2) @ K.T
    if Z is None:
        return None, None
    HZ = Z[at] * slope[:, None]
    state["Z"] = Z - K @ HZ
    if at.size == 1:
        return y / L[0, 0], -HZ / L[0, 0]
    return np.linalg.solve(L, y), -np.linalg.solve(L, HZ)
