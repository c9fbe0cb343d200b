"""The fit's trust-region stages: the pre-fit on a window (:func:`prefit`) and the whole estimation part
(:func:`full_fit`), each a direct route with the continuity weighted at once and, where that ends above
noise, a second route raising the weight in turn (:func:`two_routes`).

The trust region itself is :mod:`.trust_region`; the exact constrained problem that follows the whole fit,
:mod:`.constrained`; the thresholds, :mod:`.rules`.  ``trust_region``, ``continuation``, ``MODEL_SHORT``,
``PENALTY_WEIGHT`` and the other rules of these stages stay importable from here.
"""

from __future__ import annotations

import numpy as np

from .rules import (ABOVE_NOISE_WARNING, CLEARLY_BETTER, FIT_DEFECT_WEIGHTS, KEEP_CONSTRAINED, GIVE_UP_CLIMB,
                    GIVE_UP_STALL, MODEL_SHORT, PENALTY_WEIGHT, PREFIT_DEFECT_WEIGHTS, PREFIT_RESTARTS,
                    SHORT_SEGMENTS, TRUST_REGION_EVALUATIONS, WELL_ABOVE_MARGIN)
from .shooting import ShootingProblem
from .trust_region import continuation, trust_region

__all__ = ["two_routes", "well_above", "prefit", "full_fit", "trust_region", "continuation",
           "PREFIT_DEFECT_WEIGHTS", "FIT_DEFECT_WEIGHTS", "SHORT_SEGMENTS", "PREFIT_RESTARTS", "MODEL_SHORT",
           "PENALTY_WEIGHT", "CLEARLY_BETTER", "KEEP_CONSTRAINED", "GIVE_UP_CLIMB", "GIVE_UP_STALL"]


def well_above(rms: float, reference: float) -> bool:
    """Whether a fit's normalised residual ``rms`` ends well above ``reference`` (its pre-fit's): above
    :data:`~.rules.CLEARLY_BETTER` times ``reference`` and ``reference +`` :data:`~.rules.WELL_ABOVE_MARGIN`,
    or not finite."""
    return not (np.isfinite(rms) and rms <= max(CLEARLY_BETTER * reference, reference + WELL_ABOVE_MARGIN))


def two_routes(pb: ShootingProblem, v0, lower, upper, weights, second_route: bool = True,
               reference: float = 0.0, finish=None, max_evaluations: int = TRUST_REGION_EVALUATIONS,
               restarts: int = 0, trust_region=trust_region, continuation=continuation):
    """The trust region from ``v0`` with continuity weighted ``weights[-1]`` at once (the *direct*
    route); when that ends above the noise level (:data:`~.rules.ABOVE_NOISE_WARNING`) and
    :func:`well_above` ``reference``, and ``second_route`` allows, also the :func:`continuation` through
    ``weights`` from the same ``v0``, which replaces the direct route only when its residual is smaller by
    :data:`~.rules.CLEARLY_BETTER`.  The second route costs time only where the first failed.

    ``finish`` (optional, ``v -> (IPOPT result, normalised rms)``) is tried on the direct route's point
    before the second route; when it reaches the noise level the second route is not needed, and when it
    ends more than :data:`~.rules.MODEL_SHORT` times above noise the model lacks physics, which the second
    route cannot supply: it is not tried either.  Why: the trust region stops short of the noise on a
    stick-slip recording where the exact constrained problem does not, and the continuation was then paid
    for nothing (``docs/decisions/0004``).

    ``restarts``: each trust-region run's fresh starts after a stall (:func:`.trust_region.trust_region`).
    ``trust_region`` and ``continuation``: the two routes' solvers (stand-ins in tests).

    Returns ``(v, rms, info)`` like :func:`.trust_region.trust_region`; ``info["route"]`` names the one kept
    and ``info["routes"]`` lists each route's residual, evaluations and seconds; ``info["finished"]`` holds
    ``finish``'s ``(result, rms)`` on the direct route when it was tried.
    """
    v, rms, info = trust_region(pb, v0, lower, upper, defect_weight=weights[-1], max_evaluations=max_evaluations,
                                restarts=restarts)
    routes = [{"route": "direct", "rms_normalised": rms, "evaluations": info["evaluations"],
               "seconds": info["seconds"]}]
    best = (v, rms, {**info, "route": "direct"})
    finished = None
    wanted = second_route and not rms <= ABOVE_NOISE_WARNING and well_above(rms, reference)
    if wanted and finish is not None:
        finished = finish(v)
        routes[0]["finished_rms_normalised"] = finished[1]
        wanted = not finished[1] <= ABOVE_NOISE_WARNING
        if wanted and np.isfinite(finished[1]) and finished[1] > MODEL_SHORT:
            # the exact problem from the direct route's point ends far above noise: the model lacks physics
            # on the whole part (as a pre-fit above MODEL_SHORT says on the window), and no continuity
            # weighting supplies it
            wanted = False
            routes[0]["second_route_skipped"] = (f"IPOPT from it ends {finished[1]:.3g} times above noise "
                                                 f"(more than {MODEL_SHORT:g}): the model lacks physics here")
    if wanted:
        v_c, rms_c, info_c = continuation(pb, v0, lower, upper, weights=weights, max_evaluations=max_evaluations,
                                          restarts=restarts)
        routes.append({"route": "continuation", "rms_normalised": rms_c, "evaluations": info_c["evaluations"],
                       "seconds": info_c["seconds"]})
        # kept only when clearly better: two routes ending at the same residual (an effect the model
        # lacks, seen alike by both) are one basin, and the direct route is the one the rest was tuned on
        if rms_c * CLEARLY_BETTER < rms:
            best = (v_c, rms_c, {**info_c, "route": "continuation"})
    v, rms, info = best
    info = {**info, "routes": routes, "evaluations": sum(r["evaluations"] for r in routes),
            "seconds": sum(r["seconds"] for r in routes)}
    if finished is not None:
        info["finished"] = finished
    return v, rms, info


def prefit(pb: ShootingProblem, v0, lower, upper, second_route: bool | None = None,
           max_evaluations: int = TRUST_REGION_EVALUATIONS, **solvers):
    """The pre-fit from ``v0`` (a start tens of percent off): :func:`two_routes` with continuity
    weighted :data:`~.rules.PREFIT_DEFECT_WEIGHTS`\\ ``[-1]``, the continuation route through
    :data:`~.rules.PREFIT_DEFECT_WEIGHTS` only when both chamber pressures are recorded.

    Neither route is better everywhere.  With both pressures recorded every state but the velocity
    is measured at every sample, so a nearly independent segment (weight 10) pins the valve and
    friction parameters on its own, and the continuation finds the basin that the coupled route
    misses on stick-slip recordings.  Where both end alike, the direct route is kept (the whole fit
    recovers more from its point).  Without the pressures each segment's pressures are free start
    states, and from a start tens of percent off a decoupled segment trades them for the valve's
    critical pressure ratio: only the direct route is used (``docs/decisions/0003``).
    ``second_route`` overrides that choice; ``max_evaluations`` caps each trust-region run.

    A run that stops on the step tolerance alone above noise starts afresh from there
    :data:`~.rules.PREFIT_RESTARTS` time(s) (:func:`.trust_region.trust_region`): SciPy's step tolerance is
    relative to the whole vector, which the segment states dominate, and a region shrunk in the penalty's
    curved valley stops the run while the cost still falls (``docs/decisions/0005``).

    ``solvers``: ``trust_region`` and ``continuation`` stand-ins for :func:`two_routes` (tests).
    """
    if second_route is None:
        second_route = {"pressure_a_Pa", "pressure_b_Pa"} <= set(pb.data.signals)
    return two_routes(pb, v0, lower, upper, PREFIT_DEFECT_WEIGHTS, second_route=second_route,
                      max_evaluations=max_evaluations, restarts=PREFIT_RESTARTS, **solvers)


def full_fit(pb: ShootingProblem, v0, lower, upper, prefit_rms: float, finish=None, **solvers):
    """The trust region on the whole estimation part from the pre-fit's point: :func:`two_routes` with
    continuity weighted :data:`~.rules.PENALTY_WEIGHT`, the continuation through
    :data:`~.rules.FIT_DEFECT_WEIGHTS` (with or without pressures) when the direct route ends above noise
    and :func:`well_above` the pre-fit's residual ``prefit_rms``.

    Why the second route here: the pre-fit leaves the parameters close, but the segments past its window
    start from a chained simulation, and with continuity weighted 1e4 at once the trust region closes their
    defects by moving into a trajectory whose stick-slip events differ from the recording's.  With the weight
    at 10 first, every segment follows its own samples, the parameters settle on what all of them say, and
    raising the weight closes the defects there.  Unlike the pre-fit, the start is close, so the trade of
    unmeasured pressures against the critical pressure ratio that rules out the continuation in the pre-fit
    without pressures does not arise; and the route is kept only when clearly better.  Where the direct
    route ends near the pre-fit's residual both routes end alike and IPOPT takes it from there, so the
    second route is not tried.  When the pre-fit itself ends more than :data:`~.rules.MODEL_SHORT` times
    above noise, the model lacks physics, no continuity weighting can close that, and the second route is
    not tried either (``docs/decisions/0004``, ``0009``).
    With ``finish`` (the fitter passes IPOPT, :func:`.constrained.solve_ipopt_exact`), IPOPT is tried on the
    direct route's point before the second route, which is run only when that stays above noise (see
    :func:`two_routes`).  ``solvers``: ``trust_region`` and ``continuation`` stand-ins (tests).
    """
    return two_routes(pb, v0, lower, upper, FIT_DEFECT_WEIGHTS, second_route=prefit_rms <= MODEL_SHORT,
                      reference=prefit_rms, finish=finish, **solvers)
