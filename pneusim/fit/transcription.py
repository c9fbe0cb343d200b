"""Direct collocation of the one CasADi model over a recording, solved by IPOPT.

Decision variables (all of order one): the scaled free parameters ``theta``,
the scaled state at every sample ``X[:, k]`` and the Radau collocation stage
states ``Z`` of ``substeps`` finite elements inside each sample interval.
Constraints: the collocation equations ``h f(z_j, u_k, p) = sum_i C_ij z_i``
(Radau IIA, order ``2 degree - 1``) and continuity of the state at the sample
instants.  The valve command is held over each interval (zero-order hold, the
recorded command).  Objective: the sum of squared residuals of position (and
chamber pressures when recorded), each divided by its sensor noise standard
deviation.  IPOPT gets exact first and second derivatives from CasADi.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..model import ActuatorModel

__all__ = ["Collocation", "Solution", "state_scale"]


def state_scale(model: ActuatorModel, stroke_m: float) -> np.ndarray:
    table = {"position_m": stroke_m, "velocity_m_per_s": 0.3, "pressure_a_Pa": 1e5, "pressure_b_Pa": 1e5,
             "spool_opening": 1.0, "spool_rate_per_s": 100.0, "temperature_a_K": 300.0,
             "temperature_b_K": 300.0, "supply_pressure_Pa": 1e5}
    return np.array([table.get(s, 1.0) for s in model.state_names])


@dataclass
class Solution:
    theta: np.ndarray          #: scaled free parameters at the optimum
    states: np.ndarray         #: (N, n_states) physical states at the samples
    w: np.ndarray              #: all decision variables
    objective: float           #: sum of squared normalised residuals
    n_residuals: int
    status: str
    success: bool
    iterations: int
    seconds: float


class Collocation:
    """The fitting NLP for one recording window.

    Parameters
    ----------
    model : ActuatorModel
    p_nominal : ndarray (n_params,)
        Parameter vector (physical units); the free entries are replaced by ``theta * scales``.
    free : sequence of str
        Names of the free parameters (``model.param_names``).
    scales : ndarray (n_free,)
    command_V : ndarray (N,)
        Command the valve sees over ``[t_k, t_k + ts)``.
    measured : dict name -> (ndarray (N,), sigma)
        Measured states (``position_m``, ``pressure_a_Pa``, ``pressure_b_Pa``) with noise std; NaN = gap.
    """

    def __init__(self, model, p_nominal, free, scales, sample_time_s, command_V, measured, stroke_m,
                 substeps=2, degree=3):
        self.model, self.free = model, list(free)
        self.scales = np.asarray(scales, float)
        self.p_nominal = np.asarray(p_nominal, float)
        self.n = n = len(model.state_names)
        self.N = N = len(command_V)
        self.sx = sx = state_scale(model, stroke_m)
        self.substeps, self.degree = substeps, degree
        self.ns = ns = substeps * degree
        nth = len(self.free)
        h = sample_time_s / substeps
        tau = ca.collocation_points(degree, "radau")
        C, _, _ = ca.collocation_coeff(tau)
        C = np.array(C)

        # one sample interval, scaled variables
        xk, xn = ca.SX.sym("xk", n), ca.SX.sym("xn", n)
        zk = ca.SX.sym("zk", n * ns)
        u, p = ca.SX.sym("u"), ca.SX.sym("p", len(self.p_nominal))
        S = ca.DM(sx)
        Z = ca.reshape(zk, n, ns)
        start = xk * S
        res = []
        for e in range(substeps):
            Ze = ca.horzcat(*[Z[:, e * degree + j] * S for j in range(degree)])
            Pc = ca.horzcat(start, Ze)
            for j in range(degree):
                res.append((h * model.rhs(Ze[:, j], u, p) - ca.mtimes(Pc, ca.DM(C[:, j]))) / S)
            start = Ze[:, degree - 1]
        res.append(start / S - xn)
        interval = ca.Function("interval", [xk, zk, xn, u, p], [ca.vertcat(*res)])

        # the whole window
        theta = ca.MX.sym("theta", nth)
        X = ca.MX.sym("X", n, N)
        Zall = ca.MX.sym("Z", n * ns, N - 1)
        index = {name: i for i, name in enumerate(model.param_names)}
        entries = [ca.MX(float(v)) for v in self.p_nominal]
        for j, name in enumerate(self.free):
            entries[index[name]] = theta[j] * float(self.scales[j])
        pfull = ca.vertcat(*entries)
        g = interval.map(N - 1, "serial")(X[:, :-1], Zall, X[:, 1:], ca.DM(np.asarray(command_V, float)[:-1]).T, pfull)
        self.w = ca.vertcat(theta, ca.vec(X), ca.vec(Zall))
        self.g = ca.vec(g)
        r = []
        self.n_residuals = 0
        for name, (y, sigma) in measured.items():
            i = model.state_names.index(name)
            ok = np.isfinite(y)
            cols = np.flatnonzero(ok)
            r.append((ca.DM(y[ok]).T - X[i, cols.tolist()] * sx[i]) / sigma)
            self.n_residuals += int(ok.sum())
        self.r = ca.vec(ca.horzcat(*r)).T if False else ca.vertcat(*[ca.vec(v) for v in r])
        self.nth = nth

    def _bounds(self, theta_lo, theta_hi):
        n, N, ns = self.n, self.N, self.ns
        lo_x = np.full(n, -np.inf)
        hi_x = np.full(n, np.inf)
        names = self.model.state_names
        for s in ("pressure_a_Pa", "pressure_b_Pa", "supply_pressure_Pa"):
            if s in names:
                lo_x[names.index(s)] = 1e4 / self.sx[names.index(s)]
        lbw = np.concatenate([theta_lo, np.tile(lo_x, N), np.tile(lo_x, ns * (N - 1))])
        ubw = np.concatenate([theta_hi, np.tile(hi_x, N), np.tile(hi_x, ns * (N - 1))])
        return lbw, ubw

    def initial_w(self, theta0, states_guess):
        """Decision vector from parameters and physical states (N, n); stages copy the interval start."""
        Xs = np.asarray(states_guess, float) / self.sx
        Zs = np.repeat(Xs[:-1], self.ns, axis=0).reshape(self.N - 1, self.n * self.ns).T
        return np.concatenate([theta0, Xs.ravel(), Zs.T.ravel()])

    def solve(self, theta0, theta_lo, theta_hi, states_guess, max_iter=300, tol=1e-8, print_level=0):
        nlp = {"x": self.w, "f": 0.5 * ca.sumsqr(self.r) / max(self.n_residuals, 1), "g": self.g}
        opts = {"ipopt.print_level": print_level, "print_time": False, "ipopt.max_iter": max_iter,
                "ipopt.tol": tol, "ipopt.mu_strategy": "adaptive", "ipopt.sb": "yes"}
        solver = ca.nlpsol("fit", "ipopt", nlp, opts)
        lbw, ubw = self._bounds(theta_lo, theta_hi)
        w0 = np.clip(self.initial_w(theta0, states_guess), lbw, ubw)
        started = time.perf_counter()
        out = solver(x0=w0, lbx=lbw, ubx=ubw, lbg=0, ubg=0)
        seconds = time.perf_counter() - started
        stats = solver.stats()
        w = np.array(out["x"]).ravel()
        X = w[self.nth:self.nth + self.n * self.N].reshape(self.N, self.n) * self.sx
        obj = float(out["f"]) * 2 * max(self.n_residuals, 1)
        return Solution(w[:self.nth].copy(), X, w, obj, self.n_residuals, str(stats["return_status"]),
                        bool(stats["success"]), int(stats.get("iter_count", -1)), seconds)

    def parameter_jacobian(self, w):
        """Jacobian (n_residuals, n_free + n_states) of the normalised residuals w.r.t. ``theta`` and
        the initial state, with the trajectory eliminated through the constraints (sensitivities of
        the discretised model: ``dS/dq = -G_S^{-1} G_q``)."""
        f = ca.Function("jacs", [self.w], [ca.jacobian(self.r, self.w), ca.jacobian(self.g, self.w)])
        Jr, Jg = (self._csc(m) for m in f(w))
        nq = self.nth + self.n
        Gs, Gq = Jg[:, nq:].tocsc(), Jg[:, :nq].toarray()
        dS = -spla.splu(Gs).solve(Gq)
        return Jr[:, :nq].toarray() + Jr[:, nq:] @ dS

    @staticmethod
    def _csc(m):
        m = ca.DM(m)
        sp_ = m.sparsity()
        colind, row = np.array(sp_.colind()), np.array(sp_.row())
        return sp.csc_matrix((np.array(m.nonzeros()), row, colind), shape=m.shape)
