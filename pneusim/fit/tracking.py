"""Segment start states tracked through a recording by an extended Kalman filter at given parameters.

Why: a segment's start state carried over from a simulation of the segments before it is useless on
a recording whose piston stick-slips from sample to sample (paper 2 in open loop).  There the model is
chaotic on the fit's time scale: at the *true* parameters, segments started from the chained simulation
of the robustness set's ``s1007`` fit their samples at 0.8 times the noise for the first two segments and
at 3-20 times it from the ninth on (the 2000-sample window: 8.29).  Searching each segment's hidden
states afresh on a grid (:func:`.initial._hidden_state`) brings the window to 0.87 but costs 19 s;
filtering the whole window once, sample by sample, with the position (and pressures) correcting the
model's state after every step, gives 0.91 in 0.4 s.  The filter only helps near the truth: at the data
sheet's parameters (tens of percent off) its starts fit no better than the chained ones, so the fitter
uses it after a fit, from that fit's parameters (:func:`.stages.tracked_route`).

The filter is :class:`filterpy.kalman.ExtendedKalmanFilter`'s update; its prediction is one sample of
the fit's own integrator (:class:`~pneusim.solver.sensitivity.SensitivitySimulator`, the held command and
any transport delay as in the fit), linearised by that integrator's state sensitivities.
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from ..errors import PneusimError
from ..solver.backends import state_scales
from ..solver.sensitivity import command_schedule
from .shooting import ShootingProblem, expected_position_reading

__all__ = ["filtered_states", "PROCESS_STD"]

#: process noise std per sample, as a fraction of each state's typical magnitude
#: (:func:`~pneusim.solver.backends.state_scales`: 1 m/s, 1 bar, ...); the position's is 1e-3 of that,
#: as the model integrates it from the velocity.  Why so small: near the truth the model is right and
#: only its chaotic sensitivity needs the correction.  The window's residual from the filtered starts at
#: the true parameters, for 3e-5, 1e-4, 3e-4, 1e-3, 1e-2: ``s1007`` (no pressures, chained starts 8.29)
#: 0.87, 0.88, 0.90, 0.98, 1.88; ``s1006`` (pressures recorded, chained 4.28) 2.86, 2.15, 1.39, 1.38.
PROCESS_STD = 3e-4

#: prior std of the first state: velocity m/s, pressures Pa; other states 1 % of their typical magnitude
_FIRST_STD = {"velocity_m_per_s": 0.02, "pressure_a_Pa": 2e4, "pressure_b_Pa": 2e4}


def filtered_states(pb: ShootingProblem, theta: np.ndarray, x_first: np.ndarray) -> np.ndarray:
    """Filtered states ``(N, n)`` at every sample of ``pb``'s window, at the scaled free parameters
    ``theta``, from the first state ``x_first`` (SI).

    Each step integrates one sample from the filtered state with state sensitivities (the transition
    Jacobian), and the measured signals of that sample update it (the position through the saturating
    sensor's mean reading, :func:`.shooting.expected_position_reading`; a missing sample is skipped).
    A step the integrator cannot take keeps the state as it was.  States stay within
    :meth:`ShootingProblem.state_bounds`.
    """
    model, sim, data = pb.model, pb.sims[0], pb.data
    n, nf = pb.n, pb.n_free
    sim.set_params(pb.params_of(theta))
    scales = state_scales(model, pb.stroke_m)
    process = PROCESS_STD * scales
    process[pb.position_index] *= 1e-3
    first = np.array([_FIRST_STD.get(name, 0.01 * s) for name, s in zip(model.state_names, scales)])
    rows = np.array([i for (i, _, _, _, _) in pb.outputs])
    values = np.column_stack([values for (_, _, values, _, _) in pb.outputs])
    sigma = np.array([sigma for (_, _, _, sigma, _) in pb.outputs])
    seen_at = np.column_stack([mask for (_, _, _, _, mask) in pb.outputs])
    kf = ExtendedKalmanFilter(dim_x=n, dim_z=rows.size)
    kf.x = np.asarray(x_first, float).copy()
    kf.P = np.diag(first ** 2)
    kf.Q = np.diag(process ** 2)
    x_lo, x_hi = pb.state_bounds()
    out = np.empty((data.n_samples, n))
    for k in range(data.n_samples):
        if k > 0:
            schedule = command_schedule(data.time_s, data.command_V, k - 1, k, pb.delay_s, data.command_before_V)
            try:
                xs, S = sim.run(data.time_s[k - 1], kf.x, schedule, 2, True)
            except PneusimError:
                xs = None
            if xs is not None and np.all(np.isfinite(xs[1])):
                F = S[1][:, nf:nf + n] / pb.x_scale[None, :]     # d x_k / d x_{k-1}: the columns are scaled
                kf.x = xs[1]
                kf.P = F @ kf.P @ F.T + kf.Q
        seen = seen_at[k]
        if seen.any():
            # the model's readings and their slopes at the predicted state (filterpy asks for both there)
            at = rows[seen]
            reading, H = kf.x[at].copy(), np.zeros((at.size, n))
            H[np.arange(at.size), at] = 1.0
            position = np.flatnonzero(at == pb.position_index)
            if position.size:
                p = position[0]
                reading[p], H[p, pb.position_index] = expected_position_reading(
                    kf.x[pb.position_index], pb.stroke_m, sigma[seen][p])
            kf.update(values[k, seen], lambda x: H, lambda x: reading, R=np.diag(sigma[seen] ** 2))
        kf.x = np.clip(kf.x, x_lo, x_hi)
        out[k] = kf.x
    return out
