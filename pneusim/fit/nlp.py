"""The multiple-shooting fit as a CasADi NLP solved by IPOPT.

``minimise 0.5 / M * |r(v)|^2  subject to  g(v) = 0,  lb <= v <= ub``

where ``r`` (normalised residuals) and ``g`` (continuity defects) come from
:class:`~pneusim.fit.shooting.ShootingProblem`, whose derivatives are CVODES
forward sensitivities of the CasADi model.  Each function IPOPT needs
(objective and constraints, gradient, constraint Jacobian, Hessian of the
Lagrangian) is a :class:`casadi.Callback` reading one cached evaluation, so
CasADi never differentiates through the simulation.

The Hessian of the Lagrangian is the Gauss-Newton matrix ``J_r^T J_r / M``
(the curvature of residuals and constraints is left out, as is usual for
least squares: at a good fit the residuals are small and the Gauss-Newton
matrix is the Hessian's dominant part), damped by
``1e-3 diag(J_r^T J_r) + 1e-9 I`` along directions the residuals do not see
(a hidden state while the piston sticks, a Stribeck velocity never crossed),
where the bare matrix is singular and IPOPT's steps would wander; the damping
changes the steps, not the optimum.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy import sparse

from ..errors import SolverError
from .deadline import FitDeadlineExceeded
from .rules import GN_DAMPING, IPOPT_OBJECTIVE_CHANGE
from .shooting import ShootingProblem

__all__ = ["solve_ipopt", "IpoptResult", "damped_gauss_newton"]


@dataclass
class IpoptResult:
    v: np.ndarray
    objective: float          #: sum of squared normalised residuals
    status: str
    success: bool
    iterations: int
    seconds: float
    max_defect: float         #: largest continuity defect (state-scaled)
    formulation: str = "continuity constraints"


def damped_gauss_newton(gn):
    """The Gauss-Newton matrix ``gn`` (sparse, ``J^T J``) with :data:`GN_DAMPING` added to its diagonal:
    ``gn + diag(1e-3 diag(gn) + 1e-9)`` (sparse), what this module's IPOPT and
    :func:`.constrained.settle_gauss_newton` step with."""
    return (gn + sparse.diags(GN_DAMPING[0] * gn.diagonal() + GN_DAMPING[1])).tocsr()


class _ClimbWatch(ca.Callback):
    """IPOPT's iteration callback: asks IPOPT to stop once ``patience`` iterates in a row have an
    objective above ``limit`` times the first iterate's (IPOPT then returns ``User_Requested_Stop``).

    With ``stall = (iterations, defect_ratio)`` it also stops a run that is stuck: at iterate
    ``iterations`` its objective is above the first iterate's while its largest continuity defect is
    still above ``defect_ratio`` times the first iterate's (neither goal has been approached)."""

    def __init__(self, n_v: int, n_g: int, limit: float, patience: int, stall: tuple[int, float] | None = None):
        ca.Callback.__init__(self)
        self.n_v, self.n_g, self.limit, self.patience = n_v, n_g, limit, patience
        self.stall = stall
        self.first = None
        self.first_defect = None
        self.iterate = 0
        self.above = 0
        self.stalled = False
        self.construct("pneusim_climb_watch", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.dense(1, 1)
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.n_v, 1)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.n_g, 1)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        f = float(arg[1])
        g = np.asarray(arg[2]).ravel() if self.n_g and len(arg) > 2 and arg[2] is not None else np.zeros(0)
        defect = float(np.max(np.abs(g))) if g.size else 0.0
        if self.first is None:
            self.first, self.first_defect = f, defect
        self.above = self.above + 1 if f > self.limit * abs(self.first) else 0
        if self.stall is not None and self.iterate == self.stall[0]:
            self.stalled = f > self.first and defect > self.stall[1] * self.first_defect
        self.iterate += 1
        return [1 if self.above >= self.patience or self.stalled else 0]


class _Oracle(ca.Callback):
    """One of the NLP's functions, computed from the problem's cached evaluation at ``x``.

    ``kind``: ``values`` ``x -> (f, g)``; ``grad_f`` ``(x, p) -> (f, J_r^T r / M)``;
    ``jac_g`` ``(x, p) -> (g, J_g)``; ``hess_lag`` ``(x, p, lam_f, lam_g) -> triu(H)``.
    """

    def __init__(self, name, problem: ShootingProblem, kind: str, penalty: float | None = None):
        ca.Callback.__init__(self)
        self.pb, self.kind, self.penalty = problem, kind, penalty
        M, G, nv = problem.n_residuals, problem.n_constraints, problem.n_v
        self.M = max(M, 1)
        # CasADi stores nonzeros column by column; map our row-major blocks onto that order once
        jg = sparse.csc_matrix((np.arange(1, problem.jg_rows.size + 1, dtype=float),
                                (problem.jg_rows, problem.jg_cols)), shape=(G, nv))
        jg.sort_indices()
        self.sp_jg = ca.Sparsity(G, nv, jg.indptr.tolist(), jg.indices.tolist())
        self.jg_order = jg.data.astype(int) - 1
        jr = sparse.csc_matrix((np.ones(problem.jr_rows.size), (problem.jr_rows, problem.jr_cols)), shape=(M, nv))
        jg1 = sparse.csc_matrix((np.ones(problem.jg_rows.size), (problem.jg_rows, problem.jg_cols)), shape=(G, nv))
        h = sparse.triu(jr.T @ jr + jg1.T @ jg1 + sparse.identity(nv)).tocsc()
        h.sort_indices()
        self.sp_h = ca.Sparsity(nv, nv, h.indptr.tolist(), h.indices.tolist())
        rows, cols = self.sp_h.get_triplet()
        self.h_rows, self.h_cols = np.asarray(rows, int), np.asarray(cols, int)
        self.h_diag = self.h_rows == self.h_cols
        self.construct(name, {})

    def get_n_in(self):
        return {"values": 1, "grad_f": 2, "jac_g": 2, "hess_lag": 4, "values_jac": 3}[self.kind]

    def get_n_out(self):
        return 1 if self.kind == "hess_lag" else 2

    def get_sparsity_in(self, i):
        if self.kind == "values_jac":   # (x, nominal f, nominal g)
            return [ca.Sparsity.dense(self.pb.n_v), ca.Sparsity.dense(1), ca.Sparsity.dense(self.pb.n_constraints)][i]
        return [ca.Sparsity.dense(self.pb.n_v), ca.Sparsity(0, 1), ca.Sparsity.dense(1),
                ca.Sparsity.dense(self.pb.n_constraints)][i]

    def get_sparsity_out(self, i):
        nv, G = self.pb.n_v, self.pb.n_constraints
        if self.kind == "values":
            return [ca.Sparsity.dense(1), ca.Sparsity.dense(G)][i]
        if self.kind == "grad_f":
            return [ca.Sparsity.dense(1), ca.Sparsity.dense(nv)][i]
        if self.kind == "jac_g":
            return [ca.Sparsity.dense(G), self.sp_jg][i]
        if self.kind == "values_jac":
            return [ca.Sparsity.dense(1, nv), self.sp_jg][i]
        return self.sp_h

    def has_jacobian(self):
        # CasADi builds the Lagrangian's gradient symbolically when it sets IPOPT up
        return self.kind == "values"

    def get_jacobian(self, name, inames, onames, opts):
        self._jacobian = _Oracle(name, self.pb, "values_jac")
        return self._jacobian

    def eval(self, arg):
        try:
            return self._evaluate(arg)
        except FitDeadlineExceeded:
            # Raised here, CasADi would print the traceback and the whole input vector for this evaluation and
            # for each one IPOPT retries; not-a-number outputs end IPOPT at once instead, and the deadline is
            # raised to the caller by the evaluation of the point IPOPT returns (:func:`solve_ipopt`).
            return self._not_a_number()

    def _not_a_number(self):
        """Every output, of its own sparsity (:meth:`get_sparsity_out`), filled with not-a-number."""
        return [ca.DM(self.get_sparsity_out(i), np.nan) for i in range(self.get_n_out())]

    def _evaluate(self, arg):
        v = np.array(arg[0]).ravel()
        e = self.pb.evaluate(v, derivatives=self.kind != "values")
        f = 0.5 * float(np.dot(e["r"], e["r"])) / self.M
        if self.penalty is not None:
            f += 0.5 * self.penalty ** 2 * float(np.dot(e["g"], e["g"])) / self.M
        if self.kind == "values":
            return [f, e["g"]]
        if not e["ok"]:
            raise SolverError("the model could not be integrated at this point")
        if self.kind in ("jac_g", "values_jac"):
            jg = ca.DM(self.sp_jg, e["jg"][self.jg_order])
            if self.kind == "jac_g":
                return [e["g"], jg]
            jr, _ = self.pb.jacobians(v)
            return [ca.DM(jr.T @ e["r"] / self.M).T, jg]
        jr, jg = self.pb.jacobians(v)
        if self.kind == "grad_f":
            grad = jr.T @ e["r"]
            if self.penalty is not None:
                grad = grad + self.penalty ** 2 * (jg.T @ e["g"])
            return [f, grad / self.M]
        gn = (jr.T @ jr).tocsr()
        if self.penalty is not None:
            gn = (gn + self.penalty ** 2 * (jg.T @ jg)).tocsr()
        values = np.asarray(damped_gauss_newton(gn)[self.h_rows, self.h_cols]).ravel()
        return [ca.DM(self.sp_h, values * (float(arg[2]) / self.M))]


def solve_ipopt(problem: ShootingProblem, v0: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                max_iter: int = 60, defect_tol: float = 2e-5, objective_change_tol: float = IPOPT_OBJECTIVE_CHANGE,
                print_level: int = 0, penalty: float | None = None,
                give_up_climb: tuple[float, int] | None = None,
                give_up_stall: tuple[int, float] | None = None) -> IpoptResult:
    """Solve the shooting problem from ``v0`` within bounds ``[lower, upper]`` with IPOPT.

    The residuals come from an adaptive integrator, so they carry its error
    (about ``rtol`` relative): IPOPT's default tolerances would chase that
    noise.  It stops when three consecutive iterates have continuity defects
    below ``10 defect_tol`` (state-scaled) and change the objective by less than
    ``objective_change_tol`` relative (or, for a converged KKT point, defects
    below ``defect_tol``).

    ``give_up_climb = (factor, patience)``: stop once ``patience`` iterates in a row have an
    objective above ``factor`` times the starting point's (status ``User_Requested_Stop``), for a
    caller that would reject such a solution anyway.  ``give_up_stall = (iterations, defect_ratio)``
    (with ``give_up_climb``): stop too when at that iterate the objective is above the start's and the
    largest continuity defect above ``defect_ratio`` times the start's (see :class:`_ClimbWatch`).
    """
    oracles = {kind: _Oracle(f"pneusim_{kind}", problem, kind, penalty)
               for kind in ("values", "grad_f", "jac_g", "hess_lag")}
    v = ca.MX.sym("v", problem.n_v)
    f, g = oracles["values"](v)
    if penalty is not None:
        g = ca.MX(0, 1)
    opts = {"grad_f": oracles["grad_f"], "hess_lag": oracles["hess_lag"],
            "print_time": False, "calc_lam_p": False, "ipopt.print_level": print_level, "ipopt.sb": "yes",
            "show_eval_warnings": False,     # a point the model cannot integrate is IPOPT's to step back from
            "ipopt.max_iter": int(max_iter), "ipopt.tol": 1e-10, "ipopt.constr_viol_tol": defect_tol,
            "ipopt.acceptable_tol": 1e20, "ipopt.acceptable_dual_inf_tol": 1e20,
            "ipopt.acceptable_constr_viol_tol": 10 * defect_tol,
            "ipopt.acceptable_obj_change_tol": objective_change_tol, "ipopt.acceptable_iter": 3,
            "ipopt.mu_strategy": "monotone", "ipopt.mu_init": 1e-6, "ipopt.bound_push": 1e-8,
            "ipopt.bound_frac": 1e-8, "ipopt.nlp_scaling_method": "none"}
    if penalty is None:
        opts["jac_g"] = oracles["jac_g"]
    if give_up_climb is not None:
        opts["iteration_callback"] = _ClimbWatch(problem.n_v, g.size1(), *give_up_climb, stall=give_up_stall)
    solver = ca.nlpsol("pneusim_fit", "ipopt", {"x": v, "f": f, "g": g}, opts)
    v0 = np.clip(np.asarray(v0, float), lower, upper)
    started = time.perf_counter()
    out = solver(x0=v0, lbx=lower, ubx=upper, lbg=0.0, ubg=0.0)
    seconds = time.perf_counter() - started
    stats = solver.stats()
    v_opt = np.array(out["x"]).ravel()
    e = problem.evaluate(v_opt, derivatives=False)
    objective = float(np.dot(e["r"], e["r"])) if e["ok"] else float("inf")
    defect = float(np.max(np.abs(e["g"]))) if e["g"].size and e["ok"] else 0.0
    return IpoptResult(v_opt, objective, str(stats.get("return_status", "")), bool(stats.get("success", False)),
                       int(stats.get("iter_count", -1)), seconds, defect)
