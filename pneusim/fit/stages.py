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

__all__ = ["trust_region", "continuation", "prefit", "polish", "PREFIT_DEFECT_WEIGHTS"]

#: continuity weights of the pre-fit, in turn (see :func:`continuation`)
PREFIT_DEFECT_WEIGHTS = (10.0, 1000.0)


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


def continuation(pb: ShootingProblem, v0, lower, upper, weights=PREFIT_DEFECT_WEIGHTS, **options):
    """:func:`trust_region` with the continuity weight raised in turn through ``weights``.

    Why: from a start tens of percent off, with continuity weighted 1000 at once, the defects
    dominate the cost and the first Gauss-Newton steps move the parameters to close them; on a
    stick-slip recording that leads over a breakaway into a wrong basin, and the trust region then
    creeps along the narrow valley of the penalty until its step tolerance (paper 1, closed-loop
    pulses with pressures: normalised residual 1.96 after 35 evaluations, the Stribeck velocity at
    0.56 of the truth).  With continuity weighted 10 the segments are nearly independent: each fits
    its own 50 samples from its own start state, every segment is short, and the parameters follow
    what all segments' samples say together (there 0.037, the noise-free truth, after 22
    evaluations); raising the weight to 1000 then closes the defects in a few evaluations.

    Returns ``(v, rms, info)`` like :func:`trust_region`; ``info`` sums evaluations and seconds over
    the rounds and gives the last round's status.
    """
    v, total = v0, {"evaluations": 0, "jacobians": 0, "seconds": 0.0}
    rms, info = float("inf"), {}
    for weight in weights:
        # every round with the same stop: a looser one for the first (relative change 1e-2) halved its
        # evaluations on paper 2 but left paper 1's noise-free closed-loop pre-fit at 3.11 (0.037 with 1e-4)
        v, rms, info = trust_region(pb, v, lower, upper, defect_weight=weight, **options)
        for key in total:
            total[key] += info[key]
    return v, rms, {**info, **total, "defect_weights": list(weights)}


def prefit(pb: ShootingProblem, v0, lower, upper):
    """The pre-fit from ``v0``: the trust region with continuity weighted 1000, reached directly when
    a chamber pressure is unmeasured, through weight 10 first (:func:`continuation`) when both are
    recorded.

    With both chamber pressures recorded every state but the velocity is measured at every sample,
    so a segment on its own pins the valve and friction parameters, and nearly independent segments
    (weight 10) lead into the basin that the coupled problem misses (paper 1, closed-loop pulses:
    normalised residual 0.037 against 1.96 after 35 evaluations; paper 2, closed-loop multisine:
    1.14 against 3.0).  Without them each segment's pressures are free start states, a decoupled
    segment trades them for the valve's critical pressure ratio, and the coupled route does better
    (paper 2, closed-loop multisine: 0.98 against 3.07).

    Returns ``(v, rms, info)`` like :func:`trust_region` (``info["defect_weights"]``: the route).
    """
    measured = {name for (_, name, _, _, _) in pb.outputs}
    both = {"pressure_a_Pa", "pressure_b_Pa"} <= measured
    weights = PREFIT_DEFECT_WEIGHTS if both else PREFIT_DEFECT_WEIGHTS[-1:]
    return continuation(pb, v0, lower, upper, weights)


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

