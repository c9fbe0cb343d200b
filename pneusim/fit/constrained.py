"""The exact constrained problem from the whole fit's trust-region point: continuity as constraints.

The trust region's point is not the answer: the penalty's open defects bias it.  Two ways finish it:
:func:`settle_gauss_newton`, constrained Gauss-Newton steps where the trust region ended at noise (the
common case, cheap), and :func:`solve_ipopt_exact`, IPOPT on the constrained problem with the penalty form
as its fallback (``docs/decisions/0007``, ``0010``).

Why Gauss-Newton settling first: near the optimum IPOPT needs three acceptable iterates in a row to stop, where
one or two Gauss-Newton steps reach the same point (the first moves the parameters by a fraction of a standard
error, the next by a hundredth of one).  Without a line search a step may open the defects where stick-slip makes
the linearisation poor; IPOPT's filter line search takes those.  A step may also open them a little on its way
(then closed by the next step), so only a tenfold excess hands over.  On recordings of another simulator the
steps may not converge at all, so a step that does not halve the next one hands over at once
(``docs/decisions/0010``).

``PNEUSIM_IPOPT_PRINT=5`` in the environment prints IPOPT's iterations (for debugging a fit).
"""

from __future__ import annotations

import os

import numpy as np

from .nlp import IpoptResult, damped_gauss_newton, solve_ipopt
from .rules import (ABOVE_NOISE_WARNING, ACCEPTABLE_DEFECT_FACTOR, CONTRACTION, DEFECT_TOL_PER_RTOL, GIVE_UP_CLIMB,
                    GIVE_UP_STALL, IPOPT_OBJECTIVE_CHANGE, KEEP_CONSTRAINED, MODEL_SHORT, OPENED_DEFECTS, SETTLED_NOISE,
                    SETTLED_SCATTER_STEPS, SETTLED_STEP, SETTLED_STEPS)
from .shooting import ShootingProblem
from .uncertainty import covariance

__all__ = ["settle_gauss_newton", "solve_ipopt_exact"]


def settle_gauss_newton(pb: ShootingProblem, v, rms: float, rtol: float, lower, upper) -> IpoptResult | None:
    """The exact constrained problem solved from the whole fit's trust-region point ``v`` (normalised
    residual ``rms``) by Gauss-Newton steps (the generalised Gauss-Newton method of multiple shooting),
    where the trust region has brought the fit to noise; None where that does not settle, and IPOPT runs.

    Each step minimises the linearised residuals subject to the linearised continuity constraints
    (IPOPT's damped Gauss-Newton matrix, :func:`.nlp.damped_gauss_newton`; one sparse KKT solve).  Settled:
    the largest continuity defect within the constraint violation at which :func:`solve_ipopt_exact`'s IPOPT
    itself stops (its acceptable level, :data:`~.rules.ACCEPTABLE_DEFECT_FACTOR` times
    :data:`~.rules.DEFECT_TOL_PER_RTOL` ``rtol``) and the next step moving no free parameter by more than
    :data:`~.rules.SETTLED_STEP` of its standard error (:func:`.uncertainty.covariance`).  Not settled, and
    IPOPT's turn: the trust region ended above noise (:data:`~.rules.ABOVE_NOISE_WARNING`), a step would cross
    a bound, or ends with its largest defect above both :data:`~.rules.OPENED_DEFECTS` times the tolerance and
    the step's start's (outside the scatter below), or with a residual sum more than
    :data:`~.rules.KEEP_CONSTRAINED` times the trust region's (the bound at which :func:`solve_ipopt_exact` gives
    up the constrained IPOPT run), or the next step is more than :data:`~.rules.CONTRACTION` times the last and
    more than the scatter below (Gauss-Newton is not converging), or :data:`~.rules.SETTLED_STEPS` steps did not settle
    (:data:`~.rules.SETTLED_SCATTER_STEPS` while the residual sum no longer moves, below).

    Settled too, within the scatter of its steps (:data:`~.rules.SETTLED_NOISE`): after two steps or more, the
    residual sum moved by less than IPOPT's acceptable relative change of the objective over the last step and
    the next step moves no parameter by more than a standard error; of the last two iterates, the one with the
    smaller largest defect is the answer where that is within half the level the result warns at.  On a
    recording that stick-slips through every slow motion each linearisation misses by the integration error:
    the steps wander by hundredths to tenths of a standard error and the defects scatter near their tolerance
    while the residual no longer moves, where IPOPT then takes its forty iterations to end at the same residual
    (``docs/decisions/0100``).  There the steps go on up to :data:`~.rules.SETTLED_SCATTER_STEPS`: which
    scattered iterate first has its defects within that level is a draw of the last bits of the arithmetic
    (``docs/decisions/0108``).

    Why Gauss-Newton first, and its hand-over rules: the module's docstring.
    """
    if not rms <= ABOVE_NOISE_WARNING:
        return None
    tolerance = ACCEPTABLE_DEFECT_FACTOR * DEFECT_TOL_PER_RTOL * rtol    # the IPOPT run's acceptable level
    nf = pb.n_free
    v = np.asarray(v, float).copy()
    e = pb.evaluate(v, derivatives=True)
    if not e["ok"]:
        return None
    start = float(np.dot(e["r"], e["r"]))
    last = None                                        # the last iterate: (v, residual sum, largest defect)
    for steps in range(SETTLED_SCATTER_STEPS + 1):
        r, g = e["r"], e["g"]
        delta = _gauss_newton_step(pb, v, r, g)
        if not np.all(np.isfinite(delta)):
            return None
        defect, cost = float(np.max(np.abs(g), initial=0.0)), float(np.dot(r, r))
        step = float(np.max(np.abs(delta[:nf]) / covariance(pb, v)["std"]))   # in standard errors
        if defect <= tolerance and step <= SETTLED_STEP:
            return IpoptResult(v, cost, "Gauss_Newton_Settled", True, steps, 0.0, defect,
                               f"continuity constraints (Gauss-Newton, {steps} steps from the trust region's point)")
        scatter = (steps >= SETTLED_NOISE[0] and step <= SETTLED_NOISE[2]
                   and abs(cost - last[1]) <= IPOPT_OBJECTIVE_CHANGE * last[1])
        if scatter:
            # stick-slip: each linearisation misses by the integration error, the steps wander within a fraction
            # of a standard error and the defects scatter near the tolerance while the residual no longer moves:
            # the last two iterates are one answer, the one with the smaller defects kept
            kept_v, kept_cost, kept_defect = min([(v, cost, defect), last], key=lambda it: it[2])
            if kept_defect <= SETTLED_NOISE[1]:
                return IpoptResult(kept_v, kept_cost, "Gauss_Newton_Settled", True, steps, 0.0, kept_defect,
                                   f"continuity constraints (Gauss-Newton, {steps} steps from the trust region's "
                                   "point; settled within the scatter of its steps)")
        last = (v, cost, defect)
        trial = v + delta
        if ((steps >= SETTLED_STEPS and not scatter) or steps == SETTLED_SCATTER_STEPS
                or np.any(trial < lower) or np.any(trial > upper)
                or (steps > 0 and not step <= max(CONTRACTION * previous, SETTLED_NOISE[2]))):
            return None
        previous = step
        e = pb.evaluate(trial, derivatives=True)
        if not (e["ok"] and float(np.dot(e["r"], e["r"])) <= KEEP_CONSTRAINED * start
                and (scatter or np.max(np.abs(e["g"]), initial=0.0) <= max(OPENED_DEFECTS * tolerance, defect))):
            # a step that opens the defects: the linearisation does not hold here (stick-slip), IPOPT's turn.
            # Within the scatter the defects of one step may open past that and the next close them: the
            # answer is still only an iterate whose defects are within SETTLED_NOISE's level, and a step that
            # leaves the scatter (the residual sum moving, a step of a standard error) ends the settling
            return None
        v = trial
    return None


def _gauss_newton_step(pb: ShootingProblem, v, r, g) -> np.ndarray:
    """The generalised Gauss-Newton step at ``v`` (residuals ``r``, defects ``g``): the linearised residuals
    minimised subject to the linearised continuity, one sparse KKT solve with IPOPT's damped matrix."""
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    jr, jg = pb.jacobians(v)
    kkt = sparse.bmat([[damped_gauss_newton(jr.T @ jr), jg.T], [jg, None]]).tocsc()
    return spsolve(kkt, np.concatenate([-(jr.T @ r), -g]))[:pb.n_v]


def solve_ipopt_exact(pb: ShootingProblem, v, lower, upper, max_iter: int, rtol: float, penalty: float,
                      give_up_climb: tuple[float, int] = GIVE_UP_CLIMB,
                      give_up_stall: tuple[int, float] = GIVE_UP_STALL) -> IpoptResult:
    """IPOPT from the trust-region solution ``v``: the exact constrained problem first.

    A stick-slip event can make the linearised continuity constraints a poor guide: IPOPT's filter
    may then accept a step that restores continuity but climbs into another basin.  The constrained
    run is kept only when its residual sum stays within :data:`~.rules.KEEP_CONSTRAINED` of the trust-region
    solution's; else IPOPT solves the trust region's own problem (continuity as a penalty of weight
    ``penalty``), whose line search cannot go uphill.  ``res.formulation`` says which one gave the answer.

    The constrained run is given up once ``give_up_climb = (factor, iterates)`` iterates in a row have an
    objective above ``factor`` times the start's (:data:`~.rules.GIVE_UP_CLIMB`): where it climbs to stay, it
    climbs at once and stays, while a run that climbs a few times its start for many iterates, or spikes
    for a few (IPOPT's feasibility restoration), may still come back below it and is kept.  From a start
    more than :data:`~.rules.MODEL_SHORT` times above noise (a model that lacks physics) the constrained run
    may also stall, every step cut short by the line search, the defects barely closing while the objective
    creeps up: ``give_up_stall = (iterate, fraction)`` gives it up at that iterate when its objective is
    above the start's and its largest defect still above that fraction of the start's
    (:data:`~.rules.GIVE_UP_STALL`); near noise that rule is off (``docs/decisions/0008``).
    """
    def residual_sum(x):
        e = pb.evaluate(x, derivatives=False)
        return float(np.dot(e["r"], e["r"])) if e["ok"] else np.inf

    start = residual_sum(v)
    level = int(os.environ.get("PNEUSIM_IPOPT_PRINT", "0"))
    far_above = np.isfinite(start) and np.sqrt(start / max(pb.n_residuals, 1)) > MODEL_SHORT
    res = solve_ipopt(pb, v, lower, upper, max_iter=max_iter, defect_tol=DEFECT_TOL_PER_RTOL * rtol,
                      print_level=level, give_up_climb=give_up_climb,
                      give_up_stall=give_up_stall if far_above else None)
    res.formulation = "continuity constraints"
    given_up = res.status == "User_Requested_Stop"    # the climb watch stopped it: never kept
    if given_up or not np.isfinite(res.objective) or res.objective > KEEP_CONSTRAINED * start:
        first = res
        res = solve_ipopt(pb, v, lower, upper, max_iter=max_iter, defect_tol=DEFECT_TOL_PER_RTOL * rtol,
                          print_level=level, penalty=penalty)
        res.formulation = f"continuity penalty {penalty:g} (constraints: {first.status}, residual sum " \
                          f"{first.objective:.4g} against {start:.4g})"
        res.iterations += first.iterations
        res.seconds += first.seconds
    return res
