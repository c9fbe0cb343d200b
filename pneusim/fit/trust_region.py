"""Trust-region least squares on the shooting problem, the continuity defects as weighted residuals.

Why a trust region first (and IPOPT only near the optimum, :mod:`.constrained`): far from the optimum
(parameters tens of percent off) the shooting problem's landscape is rough (stick-slip, end stops), and a
line-search method accepts a first Gauss-Newton step that leads into a wrong basin; a trust region keeps
every step where the linearisation holds (``docs/decisions/0001``).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.sparse.linalg import LinearOperator

from ..errors import FitError
from .parameters import clip_inside
from .rules import ABOVE_NOISE_WARNING, PREFIT_DEFECT_WEIGHTS, TRUST_REGION_EVALUATIONS, TRUST_REGION_TOLERANCE
from .shooting import ShootingProblem

__all__ = ["trust_region", "continuation"]

#: SciPy's stop reasons by status
_STATUS = {-1: "improper input", 0: "evaluation limit", 1: "gradient tolerance", 2: "cost tolerance",
           3: "step tolerance", 4: "cost and step tolerance"}


def trust_region(pb: ShootingProblem, v0, lower, upper, max_evaluations: int = TRUST_REGION_EVALUATIONS,
                 defect_weight: float = PREFIT_DEFECT_WEIGHTS[-1], tolerance: float = TRUST_REGION_TOLERANCE,
                 restarts: int = 0, least_squares=None):
    """Trust-region least squares (SciPy's ``trf`` with the exact sparse Jacobian) on the shooting
    problem with the continuity defects as residuals weighted ``defect_weight``.

    IPOPT's line search lets a bad first Gauss-Newton step through when it reduces the defects; far
    from the optimum (parameters tens of percent off) that lands in local minima of the stick-slip
    landscape.  A trust region limits every step to where the linearisation holds, which is what a
    start far away needs; IPOPT then solves the exact constrained problem from here.

    Every residual is integrated with sensitivities: the trust region accepts most trial points, so one
    integration with them beats a state-only pass plus a second one.  A trial point the model cannot be
    integrated at has non-finite residuals, which make SciPy reject the step and shrink the region (a
    finite stand-in would be accepted as an improvement from any start that costs more, and there is no
    Jacobian there; ``docs/decisions/0001``).

    ``restarts``: fresh trust regions at most, each from where the last stopped, after a stop on SciPy's
    step tolerance alone above noise (``docs/decisions/0005``); ``max_evaluations`` caps them all together,
    and ``info`` counts them (``"restarts"``).

    ``least_squares``: SciPy's :func:`scipy.optimize.least_squares` unless given (a stand-in in tests).

    Returns ``(v, rms, info)``: the end point, its normalised rms residual (continuity aside) and ``info``
    with SciPy's stop reason, evaluations, Jacobians, restarts and seconds.
    """
    from scipy import sparse

    if least_squares is None:
        from scipy.optimize import least_squares

    started = time.perf_counter()
    n_r = pb.n_residuals

    def fun(v):
        e = pb.evaluate(v, derivatives=True)
        if not e["ok"]:
            return np.full(n_r + pb.n_constraints, np.inf)
        return np.concatenate([e["r"], defect_weight * e["g"]])

    def jac(v):
        e = pb.evaluate(v, derivatives=True)
        if not e["ok"]:
            raise FitError("the model could not be integrated at a trust-region trial point (its parameters "
                           "and segment start states)")
        jr, jg = pb.jacobians(v)
        return _StackedJacobian(sparse.vstack([jr, defect_weight * jg]).tocsr())

    v = clip_inside(v0, lower, upper)
    evaluations = jacobians = restarted = 0
    while True:
        try:
            fit = least_squares(fun, v, jac=jac, bounds=(lower, upper), method="trf", x_scale=1.0, tr_solver="lsmr",
                                max_nfev=max_evaluations - evaluations, xtol=tolerance, ftol=tolerance)
        except ValueError as exc:
            if "not finite in the initial point" not in str(exc):
                raise
            raise FitError("the model could not be integrated at the trust region's start point (its parameters "
                           "and segment start states)") from None
        evaluations += int(fit.nfev)
        jacobians += int(fit.njev or 0)
        v = fit.x
        r = fun(v)[:n_r]
        rms = float(np.sqrt(np.mean(r ** 2))) if np.all(np.isfinite(r)) else float("inf")
        # SciPy's step tolerance is relative to the norm of the whole vector, which the segment states
        # dominate: a region shrunk by a few rejected steps in the penalty's curved valley ends the run while
        # the cost still falls by more than the cost tolerance per step (status 3 alone).  Above noise that
        # is a stall, not convergence: start again from there with a fresh region
        if not (fit.status == 3 and rms > ABOVE_NOISE_WARNING and restarted < restarts
                and evaluations < max_evaluations):
            break
        restarted += 1
    status = _STATUS.get(fit.status, str(fit.status))
    return v, rms, {"status": status, "evaluations": evaluations, "jacobians": jacobians, "restarts": restarted,
                    "seconds": time.perf_counter() - started}


class _StackedJacobian(LinearOperator):
    """A CSR Jacobian as SciPy's LSMR multiplies it in :func:`trust_region`, with its transpose stored.

    Why: SciPy wraps a sparse Jacobian in a linear operator whose transposed product builds a conjugate copy
    of the matrix at every call, and LSMR takes one such product per iteration (over a hundred per
    trust-region step on a pre-fit window).  The products are SciPy's own sparse kernels adding each row's or
    column's terms in the same order, so the steps are the same to the last bit (``docs/decisions/0029``)."""

    def __init__(self, matrix):
        super().__init__(matrix.dtype, matrix.shape)
        self.matrix = matrix
        self.transposed = matrix.T.tocsr()

    def _matvec(self, x):
        return self.matrix @ x

    def _matmat(self, X):
        return self.matrix @ X

    def _rmatvec(self, x):
        return self.transposed @ x

    def _rmatmat(self, X):
        return self.transposed @ X


def continuation(pb: ShootingProblem, v0, lower, upper, weights=PREFIT_DEFECT_WEIGHTS, **options):
    """:func:`trust_region` with the continuity weight raised in turn through ``weights``.

    Why: from a start tens of percent off, with continuity weighted 1000 at once, the defects dominate the
    cost and the first Gauss-Newton steps move the parameters to close them; on a stick-slip recording that
    can lead over a breakaway into a wrong basin, and the trust region then creeps along the narrow valley
    of the penalty until its step tolerance.  With continuity weighted 10 the segments are nearly
    independent: each fits its own samples from its own start state, and the parameters follow what all
    segments' samples say together; raising the weight then closes the defects in a few evaluations
    (``docs/decisions/0003``).

    Returns ``(v, rms, info)`` like :func:`trust_region`; ``info`` sums evaluations and seconds over
    the rounds and gives the last round's status.
    """
    v, total = v0, {"evaluations": 0, "jacobians": 0, "seconds": 0.0}
    rms, info = float("inf"), {}
    for weight in weights:
        v, rms, info = trust_region(pb, v, lower, upper, defect_weight=weight, **options)
        for key in total:
            total[key] += info[key]
    return v, rms, {**info, **total, "defect_weights": list(weights)}
