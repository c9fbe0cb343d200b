"""The fit's rescue routes, tried where the trust-region stages (:mod:`.stages`) end above noise: the pre-fit
through short segments (both pressures recorded), segment starts tracked by a Kalman filter, and the
prediction-error fit followed by those tracked starts.  Each is kept only where it ends lower on the
problem it rescues."""

from __future__ import annotations

import time

import numpy as np

from .initial import initial_starts
from .prediction_error import prediction_error_attempts
from .rules import (ABOVE_NOISE_WARNING, CLEARLY_BETTER, FIT_DEFECT_WEIGHTS, NEARBY_START, PLAUSIBLE_INNOVATIONS,
                    PREDICTION_ERROR_ATTEMPTS, TRACKED_ROUNDS)
from .shooting import ShootingProblem
from .stages import prefit
from .tracking import filtered_states
from .trust_region import continuation

__all__ = ["short_segments_route", "tracked_route", "prediction_error_route", "nearby_start", "TRACKED_ROUNDS",
           "PLAUSIBLE_INNOVATIONS"]


def short_segments_route(short, pb: ShootingProblem, lower, upper, theta0, v, rms, recording):
    """The pre-fit's route through :data:`~.rules.SHORT_SEGMENTS`-sample segments, for a recording with both
    pressures whose pre-fit (``v``, normalised residual ``rms`` on problem ``pb``) ended above noise but not so
    far that the model lacks physics: :func:`.stages.prefit` on ``short = (problem, lower, upper)`` (the same
    window in short segments) from the same start ``theta0``, then :func:`.stages.prefit` on ``pb`` from its
    parameters with each segment starting from the measured or the carried state
    (:func:`.initial.initial_starts`' ``choose_starts``).  Kept when that ends :data:`~.rules.CLEARLY_BETTER`
    times below ``rms`` on the same problem.

    Why: a piston that stick-slips from sample to sample through every slow motion makes a 50-sample
    segment's residual depend on the phase of that oscillation; with the pressures measured only the
    velocity of a short segment's start is unknown, and short segments pin the valve and friction
    parameters.  Judged on the pre-fit's own problem, not on the short segments' residual: short segments
    with free starts also absorb a missing effect, and the pre-fit's residual is what says that the model
    lacks physics (``docs/decisions/0006``).

    Returns ``(v, rms, info)``: the kept point and residual on ``pb``, and ``info`` with the short pre-fit's
    residual, the route's residual on ``pb``, whether it was kept and its seconds.
    """
    started = time.perf_counter()
    short_pb, short_lo, short_hi = short
    try:
        v_short = short_pb.join(theta0, initial_starts(short_pb, theta0, recording, short_pb.data.n_samples))
        v_short, rms_short, _ = prefit(short_pb, v_short, short_lo, short_hi)
        theta_short, _ = short_pb.split(v_short)
    finally:
        short_pb.close()
    starts = initial_starts(pb, theta_short, recording, pb.data.n_samples, choose_starts=True)
    v_route, rms_route, _ = prefit(pb, pb.join(theta_short, starts), lower, upper)
    kept = bool(rms_route * CLEARLY_BETTER < rms)
    info = {"rms_short_normalised": rms_short, "rms_normalised": rms_route, "kept": kept,
            "seconds": time.perf_counter() - started}
    return (v_route, rms_route, info) if kept else (v, rms, info)


def tracked_route(pb: ShootingProblem, v, lower, upper, rms: float, finish):
    """From a fit ``v`` that ended above noise (normalised residual ``rms`` on ``pb``): every segment
    started from the state an extended Kalman filter tracks at the fit's parameters
    (:func:`.tracking.filtered_states`), then the :func:`.trust_region.continuation` through
    :data:`~.rules.FIT_DEFECT_WEIGHTS`; again from there while it lowers the residual,
    :data:`~.rules.TRACKED_ROUNDS` rounds at most; then ``finish`` (``(v, rms) -> (result, normalised rms)``: the
    exact constrained problem, Gauss-Newton settling where ``rms`` is at noise, else IPOPT) on the best point when
    a round lowered it.

    Why: on a recording whose piston stick-slips from sample to sample a segment started from the chained
    simulation leaves the recorded slip pattern within seconds even at the true parameters, and the trust
    region then settles where the parameters make up for the wrong slips.  From the filtered starts the
    segments follow their own samples, and the parameters what all of them say together
    (``docs/decisions/0017``).

    Returns ``(result, info)``: ``finish``'s result (None when no round lowered the residual), and
    ``info`` with each round's residual, evaluations and seconds, and the finished residual.
    """
    best, rounds = (v, rms), []
    for _ in range(TRACKED_ROUNDS):
        started = time.perf_counter()
        theta, starts = pb.split(best[0])
        filtered = filtered_states(pb, theta, starts[0])[pb.starts]
        v_new, rms_new, info = continuation(pb, pb.join(theta, filtered), lower, upper, weights=FIT_DEFECT_WEIGHTS)
        rounds.append({"rms_normalised": rms_new, "evaluations": info["evaluations"],
                       "seconds": time.perf_counter() - started})
        if not rms_new < best[1]:
            break
        best = (v_new, rms_new)
        if rms_new <= ABOVE_NOISE_WARNING:
            break
    info = {"rounds": rounds, "seconds": sum(r["seconds"] for r in rounds)}
    if not best[1] < rms:
        return None, info
    done, info["finished_rms_normalised"] = finish(*best)
    return done, info


def nearby_start(theta0: np.ndarray, attempt: int) -> np.ndarray:
    """Start ``attempt`` of a route chaotic in its start: ``theta0`` itself for attempt 0, else ``theta0`` moved by
    deterministic relative perturbations of :data:`~.rules.NEARBY_START`, uniform in ``[-1, 1]`` times that from
    a generator seeded by the attempt's number: the same starts on every machine."""
    theta0 = np.asarray(theta0, float)
    if attempt == 0:
        return theta0.copy()
    return theta0 * (1.0 + NEARBY_START * np.random.default_rng(attempt).uniform(-1.0, 1.0, theta0.size))


def prediction_error_route(window: ShootingProblem, pb: ShootingProblem, lower, upper, theta0, x_first,
                           rms: float, finish):
    """From the start ``theta0`` (scaled free parameters; ``x_first`` the first state, SI): the prediction-error
    fit on the pre-fit's ``window`` from the start and from up to :data:`~.rules.PREDICTION_ERROR_ATTEMPTS` ``- 1``
    nearby starts (:func:`nearby_start`) until two agree on the lowest end
    (:func:`.prediction_error.prediction_error_attempts`), the lowest kept; then, from its parameters and first
    state, :func:`tracked_route` on the whole estimation part ``pb`` against the best fit so far (normalised
    residual ``rms``), ``finish`` on its best point.

    Why: where the piston stick-slips from sample to sample the shooting problem's landscape is rippled by
    every mistimed slip and the pre-fit from a start tens of percent off stops in a wrong basin; the filter's
    innovations are smooth in the parameters (see :mod:`.prediction_error`).  Far from the truth, though, the
    filter can lose track of the piston, and where it does depends on the last bits of its arithmetic: one
    landing is a draw, and the fit must not hang on one (``docs/decisions/0103``).  The shooting problem still
    decides: the route's fit is kept only where its objective is lower than the best fit's.  Given up where
    the filter's innovations end a stage more than :data:`~.rules.PLAUSIBLE_INNOVATIONS` times above their noise
    level, and no other start is tried where they do so at the first (broadest) stage: a filter that cannot
    predict the recording one sample ahead says the model lacks physics, where it predicts a chaotic recording
    the model explains near its noise level (``docs/decisions/0018``).

    Returns ``(result, info)``: ``finish``'s result (None where the route stopped or no round lowered the
    residual), and ``info`` with the kept prediction-error fit's stages, its parameters, every attempt's
    innovations, the tracked route's rounds and seconds.
    """
    started = time.perf_counter()
    attempts = prediction_error_attempts(window, [nearby_start(theta0, k) for k in range(PREDICTION_ERROR_ATTEMPTS)],
                                         x_first, lower[:pb.n_free], upper[:pb.n_free],
                                         give_up_above=PLAUSIBLE_INNOVATIONS)
    rms_innovations, theta, first, pem = min(((a[2]["rms_innovations"], *a) for a in attempts if a[0] is not None),
                                             key=lambda a: (a[0], a[3]["start"]))
    info = {"prediction_error": pem, "theta": theta.tolist(),
            "attempts": [{"start": a[2]["start"], "rms_innovations": a[2]["rms_innovations"],
                          "stages": len(a[2]["stages"]), "seconds": a[2]["seconds"]} for a in attempts]}
    done = None
    if rms_innovations <= PLAUSIBLE_INNOVATIONS:
        starts = np.tile(first, (pb.n_segments, 1))   # only the first is used: the filter tracks the rest
        done, tracked = tracked_route(pb, pb.join(theta, starts), lower, upper, rms, finish)
        info.update(rounds=tracked["rounds"], finished_rms_normalised=tracked.get("finished_rms_normalised"))
    info["seconds"] = time.perf_counter() - started
    return done, info
