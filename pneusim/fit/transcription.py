"""Work in progress (issue 5, not wired to the command line or tested yet).

Multiple shooting of the one CasADi model over a recording, solved by IPOPT.

The recording window is cut into segments of ``segment_samples`` samples.
Decision variables (all of order one): the scaled free parameters ``theta`` and
the scaled state at the start of every segment.  Inside a segment the state is
propagated sample by sample with the recorded command held (zero-order hold)
by a fixed-step Radau IIA collocation integrator (``substeps`` finite elements
of ``degree`` stages per sample, order ``2 degree - 1``, solved by Newton's
method; it is L-stable, which the stiff friction and end stops need).
Constraints: continuity of the state between segments.  Objective: the sum of
squared residuals of position (and chamber pressures when recorded), each
divided by its sensor noise standard deviation.  CasADi gives exact
derivatives (through the Newton solves by the implicit-function theorem);
IPOPT uses the Gauss-Newton Hessian ``J^T J`` of the residuals.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..model import ActuatorModel

__all__ = ["MultipleShooting", "Solution", "state_scale", "step_function"]


def state_scale(model: ActuatorModel, stroke_m: float) -> np.ndarray:
    """Typical magnitude of each state, to scale decision variables and constraints."""
    table = {"position_m": stroke_m, "velocity_m_per_s": 0.3, "pressure_a_Pa": 1e5, "pressure_b_Pa": 1e5,
             "spool_opening": 1.0, "spool_rate_per_s": 100.0, "temperature_a_K": 300.0,
             "temperature_b_K": 300.0, "supply_pressure_Pa": 1e5}
    return np.array([table.get(s, 1.0) for s in model.state_names])


def step_function(model: ActuatorModel, sample_time_s: float, substeps: int = 3, degree: int = 2,
                  newton_iterations: int = 5) -> ca.Function:
    """``F(x[n], u, p) -> x_next``: one sample with the command held, Radau IIA collocation.

    The stage equations are solved by a fixed number of Newton iterations written
    out symbolically (pure SX), so ``F`` and all its derivatives are fast
    compiled-graph evaluations; the derivatives are exact for this discrete map.
    """
    n = len(model.state_names)
    h = sample_time_s / substeps
    C, _, _ = ca.collocation_coeff(ca.collocation_points(degree, "radau"))
    C = np.array(C)
    Z, x0 = ca.SX.sym("Z", n, degree), ca.SX.sym("x0", n)
    u, p = ca.SX.sym("u"), ca.SX.sym("p", model.p_sym.shape[0])
    Pc = ca.horzcat(x0, Z)
    res = ca.vertcat(*[h * model.rhs(Z[:, j], u, p) - ca.mtimes(Pc, ca.DM(C[:, j])) for j in range(degree)])
    z = ca.vec(Z)
    newton = ca.Function("newton", [z, x0, u, p], [z - ca.solve(ca.jacobian(res, z), res)])
    X0, U, P = ca.SX.sym("x", n), ca.SX.sym("u"), ca.SX.sym("p", model.p_sym.shape[0])
    x = X0
    for _ in range(substeps):
        zk = ca.repmat(x, degree, 1)
        for _ in range(newton_iterations):
            zk = newton(zk, x, U, P)
        x = zk[(degree - 1) * n:]
    return ca.Function("pneusim_step", [X0, U, P], [x], ["x", "u", "p"], ["x_next"])


def sensitivity_step(model: ActuatorModel, free_index, scales, sample_time_s: float, substeps: int,
                     degree: int = 2) -> ca.Function:
    """``Fs(x, S, u, p) -> (x_next, S_next)`` with ``S = dx/d[theta, x0]`` (n x (n_free + n)).

    Forward sensitivities of the discrete step, exact by CasADi AD; ``theta`` are
    the free parameters divided by ``scales``.
    """
    F = step_function(model, sample_time_s, substeps, degree)
    n, nth = len(model.state_names), len(free_index)
    x, u, p = ca.SX.sym("x", n), ca.SX.sym("u"), ca.SX.sym("p", model.p_sym.shape[0])
    S = ca.SX.sym("S", n, nth + n)
    xn = F(x, u, p)
    A = ca.jacobian(xn, x)
    B = ca.mtimes(ca.jacobian(xn, p)[:, list(free_index)], ca.diag(ca.DM(np.asarray(scales, float))))
    Sn = ca.mtimes(A, S) + ca.horzcat(B, ca.DM.zeros(n, n))
    return ca.Function("pneusim_sens_step", [ca.vertcat(x, ca.vec(S)), u, p], [ca.vertcat(xn, ca.vec(Sn))])


@dataclass
class Solution:
    theta: np.ndarray          #: scaled free parameters at the optimum
    starts: np.ndarray         #: (S, n) physical segment start states
    states: np.ndarray         #: (N, n) physical states at the samples (propagated)
    v: np.ndarray              #: decision variables
    objective: float           #: sum of squared normalised residuals
    n_residuals: int
    status: str
    success: bool
    iterations: int
    seconds: float


class MultipleShooting:
    """The fitting NLP for one recording window.

    Parameters
    ----------
    model : ActuatorModel
    p_nominal : ndarray (n_params,)
        Parameter vector (physical units); free entries are replaced by ``theta * scales``.
    free : sequence of str
        Names of the free parameters (``model.param_names``).
    scales : ndarray (n_free,)
    sample_time_s : float
    command_V : ndarray (N,)
        Command the valve sees over ``[t_k, t_k + ts)``.
    measured : dict state name -> (ndarray (N,), sigma)
        Measured states with their noise std; NaN marks a gap.
    stroke_m : float
    segment_samples : int
    step : casadi.Function, optional
        A ready :func:`step_function` (reused between problems).
    """

    def __init__(self, model, p_nominal, free, scales, sample_time_s, command_V, measured, stroke_m,
                 segment_samples=100, substeps=3, degree=2, step=None):
        self.model, self.free = model, list(free)
        self.scales = np.asarray(scales, float)
        self.p_nominal = np.asarray(p_nominal, float)
        self.n = n = len(model.state_names)
        L = max(2, int(segment_samples))
        N = len(command_V)
        S = max(1, (N - 1) // L)
        self.L, self.S, self.N = L, S, S * L + 1
        self.sx = sx = state_scale(model, stroke_m)
        nth = self.nth = len(self.free)
        F = step if step is not None else step_function(model, sample_time_s, substeps, degree)
        seg = F.mapaccum("segment", L)

        theta = ca.MX.sym("theta", nth)
        starts = ca.MX.sym("s", n, S)
        index = {name: i for i, name in enumerate(model.param_names)}
        entries = [ca.MX(float(v)) for v in self.p_nominal]
        for j, name in enumerate(self.free):
            entries[index[name]] = theta[j] * float(self.scales[j])
        pfull = ca.vertcat(*entries)
        U = np.asarray(command_V, float)[:S * L].reshape(S, L)
        sphys = starts * ca.DM(sx)
        X = seg.map(S, "thread", 2)(sphys, ca.DM(U.reshape(1, S * L)), pfull)  # n x (S*L): samples 1..S*L
        traj = ca.horzcat(sphys[:, 0], X)                                       # samples 0..S*L
        self.v = ca.vertcat(theta, ca.vec(starts))
        ends = ca.horzcat(*[X[:, (j + 1) * L - 1] for j in range(S - 1)]) if S > 1 else ca.MX(n, 0)
        # continuity; sample j*L is both the end of segment j-1 and the start s_j (used in residuals)
        self.g = ca.vec((ends - sphys[:, 1:]) / ca.DM(sx)) if S > 1 else ca.MX(0, 1)
        cols_start = [j * L for j in range(S)]
        r = []
        self.n_residuals = 0
        for name, (y, sigma) in measured.items():
            i = model.state_names.index(name)
            y = np.asarray(y, float)[:self.N]
            ok = np.flatnonzero(np.isfinite(y))
            # samples that start a segment use s_j, others the propagated trajectory
            model_y = ca.horzcat(*[sphys[i, k // L] if k in cols_start else traj[i, k] for k in []]) if False else None
            r.append((ca.DM(y[ok]).T - traj[i, ok.tolist()]) / sigma)
            self.n_residuals += int(ok.size)
        self.r = ca.vertcat(*[ca.vec(v) for v in r])
        self.traj = ca.Function("traj", [self.v], [traj.T])
        self.residuals = ca.Function("residuals", [self.v], [self.r])

    def initial_v(self, theta0, states_guess):
        starts = np.asarray(states_guess, float)[0:self.S * self.L:self.L] / self.sx
        return np.concatenate([theta0, starts.ravel()])

    def solve(self, theta0, theta_lo, theta_hi, states_guess, max_iter=100, tol=1e-8, print_level=0):
        """IPOPT from ``theta0`` and physical states ``states_guess`` (N, n) at the samples."""
        nres = max(self.n_residuals, 1)
        Jr = ca.jacobian(self.r, self.v)
        lam_f, lam_g, pp = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", self.g.shape[0]), ca.MX.sym("p", 0)
        hess = ca.Function("hess_gn", [self.v, pp, lam_f, lam_g], [lam_f * ca.triu(ca.mtimes(Jr.T, Jr)) / nres],
                           ["x", "p", "lam_f", "lam_g"], ["hess"])
        nlp = {"x": self.v, "f": 0.5 * ca.sumsqr(self.r) / nres, "g": self.g}
        opts = {"ipopt.print_level": print_level, "print_time": False, "ipopt.max_iter": max_iter,
                "ipopt.tol": tol, "ipopt.acceptable_tol": 1e-5, "ipopt.sb": "yes", "hess_lag": hess}
        solver = ca.nlpsol("pneusim_fit", "ipopt", nlp, opts)
        lbv = np.concatenate([theta_lo, np.full(self.n * self.S, -np.inf)])
        ubv = np.concatenate([theta_hi, np.full(self.n * self.S, np.inf)])
        v0 = np.clip(self.initial_v(theta0, states_guess), lbv, ubv)
        started = time.perf_counter()
        out = solver(x0=v0, lbx=lbv, ubx=ubv, lbg=0, ubg=0)
        seconds = time.perf_counter() - started
        stats = solver.stats()
        v = np.array(out["x"]).ravel()
        obj = float(out["f"]) * 2 * nres
        states = np.array(self.traj(v))
        starts = v[self.nth:].reshape(self.S, self.n) * self.sx
        return Solution(v[:self.nth].copy(), starts, states, v, obj, self.n_residuals,
                        str(stats["return_status"]), bool(stats["success"]), int(stats.get("iter_count", -1)),
                        seconds)

    def parameter_jacobian(self, v):
        """Jacobian (n_residuals, n_free + n_states) of the normalised residuals w.r.t. ``theta`` and
        the initial state, the later segment starts eliminated through the continuity constraints
        (``dS/dq = -G_S^{-1} G_q``): the sensitivities of one simulation over the whole window."""
        f = ca.Function("jacs", [self.v], [ca.jacobian(self.r, self.v), ca.jacobian(self.g, self.v)])
        Jr, Jg = (np.array(ca.DM(m)) for m in f(v))
        nq = self.nth + self.n
        if Jg.shape[0] == 0:
            return Jr[:, :nq]
        dS = -np.linalg.solve(Jg[:, nq:], Jg[:, :nq])
        return Jr[:, :nq] + Jr[:, nq:] @ dS
