"""The solver stages of the fit: trust-region least squares with continuity as a weighted residual,
then IPOPT on the exact constrained problem.

Why two solvers: far from the optimum (parameters tens of percent off) the shooting problem's
landscape is rough (stick-slip, end stops), and a line-search method such as IPOPT accepts a first
Gauss-Newton step that leads into a wrong basin; a trust region keeps every step where the
linearisation holds.  Near the optimum IPOPT solves the exact problem, continuity as constraints.

``PNEUSIM_IPOPT_PRINT=5`` in the environment prints IPOPT's iterations (for debugging a fit).
"""

from __future__ import annotations

import os
import time

import numpy as np

from ..errors import FitError
from .nlp import solve_ipopt
from .shooting import ShootingProblem

__all__ = ["trust_region", "polish"]


def trust_region(pb: ShootingProblem, v0, lower, upper, max_evaluations: int = 80, defect_weight: float = 1000.0,
            tolerance: float = 1e-4):
    """Trust-region least squares (SciPy's ``trf`` with the exact sparse Jacobian) on the shooting
    problem with the continuity defects as heavily weighted residuals.

    IPOPT's line search lets a bad first Gauss-Newton step through when it reduces the defects; far
    from the optimum (parameters tens of percent off) that lands in local minima of the stick-slip
    landscape.  A trust region limits every step to where the linearisation holds, which is what a
    start far away needs; IPOPT then solves the exact constrained problem from here.
    """
    from scipy import sparse
    from scipy.optimize import least_squares

    started = time.perf_counter()
    n_r = pb.n_residuals

    # residuals with sensitivities: the trust region accepts most trial points (17 of 20 on a stuck
    # closed-loop pre-fit), so integrating once with them beats a state-only pass plus a second one
    def fun(v):
        e = pb.evaluate(v, derivatives=True)
        if not e["ok"]:
            return np.full(n_r + pb.n_constraints, 1e3)
        return np.concatenate([e["r"], defect_weight * e["g"]])

    def jac(v):
        e = pb.evaluate(v, derivatives=True)
        if not e["ok"]:
            raise FitError("the model could not be integrated at the pre-fit's point")
        jr, jg = pb.jacobians(v)
        return sparse.vstack([jr, defect_weight * jg]).tocsr()

    # strictly inside finite bounds; an infinite bound (spool and temperature states) stays infinite
    # (inf * 1e-12 * |inf| would be NaN)
    with np.errstate(invalid="ignore"):   # np.where evaluates both branches: inf - inf is NaN there
        inner_lower = np.where(np.isfinite(lower), lower + 1e-12 * np.abs(lower), lower)
        inner_upper = np.where(np.isfinite(upper), upper - 1e-12 * np.abs(upper), upper)
    v0 = np.clip(v0, inner_lower, inner_upper)
    fit = least_squares(fun, v0, jac=jac, bounds=(lower, upper), method="trf", x_scale=1.0,
                        tr_solver="lsmr", max_nfev=max_evaluations, xtol=tolerance, ftol=tolerance)
    r = fun(fit.x)[:n_r]
    rms = float(np.sqrt(np.mean(r ** 2))) if np.all(np.isfinite(r)) else float("inf")
    status = {-1: "improper input", 0: "evaluation limit", 1: "gradient tolerance", 2: "cost tolerance",
              3: "step tolerance", 4: "cost and step tolerance"}.get(fit.status, str(fit.status))
    return fit.x, rms, {"status": status, "evaluations": int(fit.nfev), "jacobians": int(fit.njev or 0),
                        "seconds": time.perf_counter() - started}


def polish(pb: ShootingProblem, v, lower, upper, max_iter: int, rtol: float, penalty: float):
    """IPOPT from the trust-region solution ``v``: the exact constrained problem first.

    A stick-slip event can make the linearised continuity constraints a poor guide: IPOPT's filter
    may then accept a step that restores continuity but climbs into another basin.  The constrained
    run is kept only when its residual sum stays within 10 % of the trust-region solution's; else
    IPOPT solves the trust region's own problem (continuity as a penalty of weight ``penalty``),
    whose line search cannot go uphill.  ``res.formulation`` says which one gave the answer.
    """
    def residual_sum(x):
        e = pb.evaluate(x, derivatives=False)
        return float(np.dot(e["r"], e["r"])) if e["ok"] else np.inf

    start = residual_sum(v)
    level = int(os.environ.get("PNEUSIM_IPOPT_PRINT", "0"))
    res = solve_ipopt(pb, v, lower, upper, max_iter=max_iter, defect_tol=20 * rtol, print_level=level)
    res.formulation = "continuity constraints"
    if not np.isfinite(res.objective) or res.objective > 1.1 * start:
        first = res
        res = solve_ipopt(pb, v, lower, upper, max_iter=max_iter, defect_tol=20 * rtol, print_level=level,
                          penalty=penalty)
        res.formulation = f"continuity penalty {penalty:g} (constraints: {first.status}, residual sum " \
                          f"{first.objective:.4g} against {start:.4g})"
        res.iterations += first.iterations
        res.seconds += first.seconds
    return res
