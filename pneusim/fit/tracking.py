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
measurements that read states directly, one value at a time); its prediction is one sample of the fit's own
integrator (:class:`~pneusim.solver.sensitivity.SensitivitySimulator`, the held command and any transport delay
as in the fit), linearised by that integrator's state sensitivities.  The pass over the samples is compiled
(:mod:`._filter`): the same doubles on every processor, whichever kernels OpenBLAS picks, and a quarter to a
third of the time NumPy's small matrices took (``docs/decisions/0105``).  The same filter
(:func:`run_filter`) gives the prediction-error fit (:mod:`.prediction_error`) its whitened innovations and
their fixed-gain Jacobian.
"""

from __future__ import annotations

import numpy as np

from ..errors import SolverError
from ..solver.backends import state_scales
from ..solver.sensitivity import command_schedule
from . import deadline
from ._filter import filter_pass
from .rules import FIRST_STATE_STD, PROCESS_STD
from .shooting import ShootingProblem

__all__ = ["filtered_states", "run_filter", "FilterCancelled", "process_std", "first_state_std", "PROCESS_STD"]


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


def process_std(pb: ShootingProblem, fraction: float = PROCESS_STD, unmeasured_factor: float = 1.0) -> np.ndarray:
    """Process noise std per sample and state (SI): ``fraction`` of each state's typical magnitude, the
    position's 1e-3 of that (the model integrates it from the velocity), and ``unmeasured_factor`` of that for the
    states no recording measures beyond the piston's motion: the chamber pressures where the window does not
    measure them, and every effect's own states (chamber temperatures, the spool, the supply line)."""
    scales = state_scales(pb.model, pb.stroke_m)
    out = fraction * scales
    out[pb.position_index] *= 1e-3
    measured = {name for (_, name, _, _, _) in pb.outputs}
    effect_states = {name for effect in pb.model.effects for name in effect.states}
    for i, name in enumerate(pb.model.state_names):
        if (name in ("pressure_a_Pa", "pressure_b_Pa") and name not in measured) or name in effect_states:
            out[i] *= unmeasured_factor
    return out


def first_state_std(pb: ShootingProblem) -> np.ndarray:
    """Prior std of the first state (SI): :data:`.rules.FIRST_STATE_STD`, else 1 % of the state's typical magnitude."""
    scales = state_scales(pb.model, pb.stroke_m)
    return np.array([FIRST_STATE_STD.get(name, 0.01 * s) for name, s in zip(pb.model.state_names, scales)])


def run_filter(pb: ShootingProblem, theta: np.ndarray, x_first: np.ndarray, process: np.ndarray,
               gradients: bool = False, sim=None, cancelled=None, stop_at_failure: bool = False) -> dict:
    """The extended Kalman filter over ``pb``'s window at the scaled free parameters ``theta`` from the first
    state ``x_first`` (SI), with process noise std ``process`` (SI, per state and sample), integrated by ``sim``
    (one of ``pb.sims``, the first by default: passes side by side each take another).  Where ``cancelled`` (a
    :class:`threading.Event`) is set, the pass raises :class:`FilterCancelled` at its next sample.  With
    ``stop_at_failure`` the pass ends at the first sample the integrator cannot take (``"ok"`` False, the
    states, innovations and Jacobian after it not written): for a caller that discards a pass with a
    failed step, as the prediction-error fit does.  Why: a trial point the model cannot be integrated at
    usually fails at every sample from there on, each failure after the integrator's whole step allowance
    (50 000 steps), so one such pass over 2000 samples took minutes where a good one takes a tenth of a second.

    Returns ``{"states": (N, n) filtered states, "ok": whether every step integrated}``; with ``gradients``
    also ``"innovations"``: the whitened innovations ``L_k^-1 (y_k - h(x_k^-))`` of every measured value
    (``S_k = L_k L_k^T`` their predicted covariance; a missing value gives 0), and ``"jacobian"``: their
    derivative with respect to ``(theta, x_first / pb.x_scale)``, the gain held fixed (the usual
    prediction-error gradient: the state sensitivities propagate through the model's one-sample
    sensitivities and the update's ``I - K H``), shape ``(N * n_measured, n_free + n)``.
    """
    deadline.check()   # a caller's processor-time deadline ends the fit here (see .deadline)
    sim, data = pb.sims[0] if sim is None else sim, pb.data
    n, nf = pb.n, pb.n_free
    sim.set_params(pb.params_of(theta))
    rows = np.array([i for (i, _, _, _, _) in pb.outputs], dtype=np.int64)
    values = np.ascontiguousarray(np.column_stack([values for (_, _, values, _, _) in pb.outputs]), dtype=float)
    sigma = np.array([sigma for (_, _, _, sigma, _) in pb.outputs], dtype=float)
    seen = np.ascontiguousarray(np.column_stack([mask for (_, _, _, _, mask) in pb.outputs]), dtype=np.uint8)
    x_lo, x_hi = pb.state_bounds()
    states = np.empty((data.n_samples, n))
    innovations = np.zeros((data.n_samples, rows.size) if gradients else (1, rows.size))
    jacobian = np.zeros((data.n_samples, rows.size, nf + n) if gradients else (1, rows.size, nf + n))
    Z0 = np.zeros((n, nf + n))   # d x / d (theta, x_first scaled)
    Z0[:, nf:] = np.diag(pb.x_scale)
    # a sample that cannot be integrated is the filter's to take; a caller's deadline ends the pass at its next sample
    step = deadline.checked(sim.step_into)
    if cancelled is not None:
        step = _cancellable(step, cancelled)
    ok = filter_pass(step, SolverError, np.ascontiguousarray(data.time_s, dtype=float),
                     _sample_schedules(pb),
                     np.ascontiguousarray(x_first, dtype=float), np.diag(first_state_std(pb) ** 2), Z0,
                     np.asarray(process, float) ** 2, 1.0 / pb.x_scale, np.ascontiguousarray(x_lo, dtype=float),
                     np.ascontiguousarray(x_hi, dtype=float), rows, values, sigma, seen, pb.position_index,
                     pb.stroke_m, nf, states, innovations, jacobian, gradients, stop_at_failure)
    result = {"states": states, "ok": bool(ok)}
    if gradients:
        result["innovations"] = innovations.ravel()
        result["jacobian"] = jacobian.reshape(-1, nf + n)
    return result


class FilterCancelled(Exception):
    """A filter pass stopped because its caller no longer needs it (:func:`run_filter`'s ``cancelled``)."""


def _cancellable(step, cancelled):
    """``step`` that first raises :class:`FilterCancelled` once the event ``cancelled`` is set."""
    def step_unless_cancelled(*args):
        if cancelled.is_set():
            raise FilterCancelled()
        return step(*args)
    return step_unless_cancelled


def _sample_schedules(pb: ShootingProblem) -> list:
    """Each sample's integration schedule over ``pb``'s window (None for the first): the commands the valve sees
    from sample ``k - 1`` to ``k`` (:func:`~pneusim.solver.sensitivity.command_schedule`), computed once per
    problem (they depend on the recording and the delay, not on the parameters)."""
    cached = getattr(pb, "_filter_schedules", None)
    if cached is None:
        data = pb.data
        cached = [None] + [tuple(np.ascontiguousarray(a) for a in
                                 command_schedule(data.time_s, data.command_V, k - 1, k, pb.delay_s,
                                                  data.command_before_V))
                           for k in range(1, data.n_samples)]
        pb._filter_schedules = cached
    return cached
