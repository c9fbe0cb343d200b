"""States and their sensitivities over a command schedule, for the parameter fit.

The fit needs ``dx(t_k)/dθ`` and ``dx(t_k)/dx(t_0)`` at every sample.  CasADi
derives the sensitivity equations from the one model,

``S' = f_x(x, u, p) S + [f_p(x, u, p)[:, free] diag(scales) | 0]``,  ``S(t_0) = [0 | diag(x_scale)]``,

where the columns are the free parameters (divided by their scales, so that
each direction is of order one) followed by the initial state (divided by the
state scales).  CasADi generates C for ``f``, ``f_x`` and the sensitivity
right-hand side; SUNDIALS CVODES integrates state and sensitivities together
(:mod:`pneusim.solver._cvodes_sensitivity`).  The result is the derivative of
the simulated samples, exact up to the integration tolerance.
"""

from __future__ import annotations

from typing import Sequence

import casadi as ca
import numpy as np

from ..errors import SolverError
from ..model import ActuatorModel
from . import work
from .backends import state_scales
from .codegen import compile_functions

__all__ = ["SensitivitySimulator", "command_schedule"]


def command_schedule(time_s: np.ndarray, command_V: np.ndarray, start: int, stop: int, delay_s: float = 0.0,
                     command_before_V: float | None = None):
    """Integration intervals from sample ``start`` to sample ``stop`` with the commands the valve sees.

    Command ``command_V[k]`` is sent at ``time_s[k]`` and held (zero-order
    hold).  With a transport delay the valve sees it from ``time_s[k] + delay_s``;
    before the first command reaches it, it sees ``command_before_V`` (default:
    the first command, i.e. the rig was holding it).

    Returns
    -------
    t_stop : ndarray (m,)
        Ends of the integration intervals, after ``time_s[start]``.
    u : ndarray (m,)
        Command the valve sees on each interval [V].
    out_index : ndarray (m,) of int64
        ``k - start`` when ``t_stop`` is the sample instant ``time_s[k]``, else -1.
    """
    time_s = np.asarray(time_s, float)
    command_V = np.asarray(command_V, float)
    before = command_V[0] if command_before_V is None else float(command_before_V)
    samples = time_s[start + 1:stop + 1]
    if delay_s <= 0.0:
        return samples.copy(), command_V[start:stop].copy(), np.arange(1, stop - start + 1, dtype=np.int64)

    t0 = time_s[start]
    arrivals = time_s + delay_s
    eps = 1e-9 * (time_s[1] - time_s[0])
    # an arrival within rounding of the interval's start is the start itself: a delay of a whole number
    # of samples puts time_s[k] + delay_s a hair after time_s[k + m] (0.342 + 0.008 > 0.35), and an
    # interval that short makes CVODES refuse to start (flag -27, "tout too close to t0")
    switches = arrivals[(arrivals > t0 + eps) & (arrivals < time_s[stop])]

    def seen(t):
        # the latest command whose delayed arrival is at or before t (within rounding)
        i = np.searchsorted(arrivals, t + eps, side="right") - 1
        return before if i < 0 else command_V[i]

    points = np.unique(np.concatenate([samples, switches]))
    # merge points closer than rounding (a delay that is a whole number of samples)
    keep = np.concatenate([[True], np.diff(points) > eps])
    points = points[keep]
    t_stop, u, out = [], [], []
    last = t0
    for t in points:
        u.append(seen(last))
        t_stop.append(t)
        k = np.searchsorted(samples, t - eps)
        out.append(k + 1 if k < samples.size and abs(samples[k] - t) <= eps else -1)
        last = t
    return np.array(t_stop), np.array(u), np.array(out, dtype=np.int64)


class SensitivitySimulator:
    """CVODES over command schedules with forward sensitivities (compiled kernels).

    Parameters
    ----------
    model : ActuatorModel
    free : sequence of str
        Free parameters (names of ``model.param_names``).
    params : ndarray (n_params,)
        Parameter vector in SI units; :meth:`set_params` changes it.
    scales : ndarray (n_free,)
        Scale of each free parameter: the sensitivity columns are ``d x / d (p_i / scale_i)``.
    stroke_m : float
        For the state scales (tolerances, initial-state columns).
    rtol : float
        Relative tolerance of the state; absolute tolerances ``rtol * state scale``.
    state_scale : ndarray (n,), optional
        Scale of the initial-state columns (default: the solver's state scales).
    linear_algebra : str
        ``"small"`` (default) or ``"sundials"``: CVODES's vectors, Newton matrix and linear solver from
        ``small_vector.h``/``small_dense.h`` or SUNDIALS' own (the same doubles, slower; the tests' peer).
    corrector : str
        ``"augmented"`` (default): state and sensitivities integrated as one state ``[x; vec(S)]`` by CVODES
        without its sensitivity module, the Newton matrix's leading block ``I - gamma f_x`` factored and
        applied to every block (``small_dense.h``'s block solver), set up at every step.  ``"staggered"``:
        CVODES's staggered corrector.  The same states to the tolerance and sensitivities as accurate
        (position sensitivities on the paper-2 benchmark's pre-fit window against an rtol 1e-10 reference:
        median error 0.17 % of each column's range against 0.15 %, largest 3.3 % both); one evaluation of
        that window takes a third of the staggered corrector's time on one thread (``benchmarks/test_bench_fit.py``
        measures both; ``docs/decisions/0019``).  Models with
        more than :data:`._cvodes_sensitivity.BLOCK_MAX_STATES` (8) states, and ``linear_algebra="sundials"``,
        use the staggered corrector.
    """

    def __init__(self, model: ActuatorModel, free: Sequence[str], params: np.ndarray, scales: np.ndarray,
                 stroke_m: float, rtol: float = 1e-6, state_scale: np.ndarray | None = None,
                 linear_algebra: str = "small", corrector: str = "augmented"):
        from . import _cvodes_sensitivity as fast

        self.model = model
        self.free = list(free)
        self.n = n = len(model.state_names)
        self.n_free = len(self.free)
        self.ns = self.n_free + n
        self.params = np.ascontiguousarray(params, dtype=float).copy()
        tolerance_scale = state_scales(model, stroke_m)
        self.x_scale = tolerance_scale if state_scale is None else np.asarray(state_scale, float)
        self.weights = np.ascontiguousarray(np.concatenate([np.asarray(scales, float), self.x_scale]))
        self.rtol = float(rtol)
        kernels = _compiled_kernels(model, tuple(self.free))
        self._keep = kernels
        atol = np.ascontiguousarray(self.rtol * tolerance_scale)
        if corrector not in ("augmented", "staggered"):
            raise ValueError(f"corrector: 'augmented' or 'staggered', got {corrector!r}")
        if linear_algebra != "small" or n > fast.BLOCK_MAX_STATES:
            corrector = "staggered"
        self.corrector = corrector
        self._integrator = fast.SensitivityIntegrator(kernels, n, self.ns, self.params, self.weights,
                                                      self.rtol, atol, linear_algebra=linear_algebra,
                                                      corrector=corrector)
        # S(t0) (n, ns): zero for the parameters, diag(x_scale) for the initial state
        self._s0 = np.zeros((n, self.ns))
        self._s0[:, self.n_free:] = np.diag(self.x_scale)

    def set_params(self, params: np.ndarray) -> None:
        """Replace the parameter vector (SI units) in place: the compiled kernels read it."""
        self.params[:] = params

    def run(self, t0: float, x0: np.ndarray, schedule, n_out: int, sensitivities: bool = True):
        """Integrate from ``(t0, x0)`` over ``schedule = (t_stop, u, out_index)``.

        Returns ``(x, S)``: states ``(n_out, n)`` at the output rows (row 0 is
        ``x0``) and, with ``sensitivities``, ``S`` of shape ``(n_out, n, ns)``
        (else ``None``).
        """
        t_stop, u, out_index = schedule
        x_out = np.full((n_out, self.n), np.nan)
        x_out[0] = x0
        s_out = np.zeros((n_out if sensitivities else 1, self.n, self.ns))
        if sensitivities:
            s_out[0] = self._s0
        steps = self._integrator.steps_taken
        flag, t_reached, message = self._integrator.run(
            float(t0), np.ascontiguousarray(x0, float), self._s0, t_stop, u, out_index,
            x_out, s_out, sensitivities)
        work.charge_steps(self._integrator.steps_taken - steps, self.n, 1 + self.ns if sensitivities else 1)
        if flag < 0:
            raise SolverError(f"CVODES failed at t = {t_reached:.6f} s (flag {flag}"
                              + (f": {message.strip()}" if message else "") + ")")
        return x_out, (s_out if sensitivities else None)

    def step_into(self, t0: float, x0: np.ndarray, schedule, x_out: np.ndarray, s_out: np.ndarray) -> None:
        """One sample with sensitivities into the caller's buffers: like :meth:`run` with ``n_out = 2``, the state
        at the sample's end written to ``x_out[1]`` (``x_out`` (2, n)) and its sensitivities to ``s_out[1]``
        (``s_out`` (2, n, ns)), C-contiguous doubles that the caller reuses from sample to sample.

        Why: the tracking filter takes one sample at a time, thousands per pass; :meth:`run`'s fresh arrays
        cost as much as the sample's integration."""
        t_stop, u, out_index = schedule
        steps = self._integrator.steps_taken
        flag, t_reached, message = self._integrator.run(float(t0), x0, self._s0, t_stop, u, out_index, x_out, s_out,
                                                        True)
        work.charge_steps(self._integrator.steps_taken - steps, self.n, 1 + self.ns)
        if flag < 0:
            raise SolverError(f"CVODES failed at t = {t_reached:.6f} s (flag {flag}"
                              + (f": {message.strip()}" if message else "") + ")")


_KERNELS: dict = {}


def _compiled_kernels(model: ActuatorModel, free: tuple[str, ...]) -> dict:
    """Compiled ``rhs``, ``jac`` and sensitivity right-hand side of ``model`` for ``free`` (cached)."""
    key = (model.describe(), model.param_names, free)
    if key in _KERNELS:
        return _KERNELS[key]
    n = len(model.state_names)
    index = [model.param_names.index(name) for name in free]
    x, u, p = model.x_sym, model.u_sym, model.p_sym
    ns = len(index) + n
    S = ca.SX.sym("S", n, ns)
    w = ca.SX.sym("w", ns)
    f = model.xdot_sym
    forcing = ca.horzcat(ca.jacobian(f, p)[:, index], ca.SX.zeros(n, n)) if index else ca.SX.zeros(n, n)
    f_x = ca.jacobian(f, x)
    s_dot = ca.mtimes(f_x, S) + ca.mtimes(forcing, ca.diag(w))
    tag = "_".join(e.name for e in model.effects) or "nominal"
    functions = [
        ca.Function(f"pneusim_sens_{tag}_rhs", [x, u, p], [f]),
        ca.Function(f"pneusim_sens_{tag}_jac", [x, u, p], [ca.densify(f_x)]),
        ca.Function(f"pneusim_sens_{tag}_srhs", [x, u, p, S, w], [ca.densify(s_dot)]),
        # the augmented corrector's right-hand side in one call: f and S' share their subexpressions (1150
        # instructions against 330 + 1142 at 4 states and 7 parameters), and f_x, which S' computes anyway,
        # comes out for the Newton matrix at the same point (the same expression, so the same doubles)
        ca.Function(f"pneusim_sens_{tag}_aug", [x, u, p, S, w], [f, ca.densify(s_dot), ca.densify(f_x)]),
    ]
    compiled = compile_functions(functions, prefix=f"pneusim_sens_{tag}", max_args=None)
    kernels = {key_: compiled[fn.name()] for key_, fn in zip(("rhs", "jac", "sens", "aug"), functions)}
    _KERNELS[key] = kernels
    return kernels
