"""The prediction-error fit: free parameters (and the first state) that minimise the innovations of an
extended Kalman filter over a window, the one-step-ahead predictor of :mod:`.tracking`.

Why: a recording whose piston stick-slips from sample to sample (paper 2 in open loop, paper 1's
closed-loop multisine without pressures) is chaotic on the fit's time scale.  The shooting problem's
residual then depends on the phase of every slip, and its landscape in the friction parameters is
rippled by every mistimed micro-slip: from the data sheet's values the pre-fit stops in a wrong basin,
whatever the starts.  The filter corrects the state after every sample, so its innovations depend
smoothly on the parameters: along the line from a chaotic recording's data-sheet values to its truth
the filter's negative log-likelihood falls monotonically to its minimum at the truth, where the shooting
residual does not.  Far from the truth the filter can still lose track of the piston, and where it does
depends on the integrator's rounding (``docs/decisions/0018``).

The process noise is what smooths the landscape and what lets the filter absorb a wrong model: the fit
lowers it in turn (:data:`~.rules.PROCESS_SCHEDULE`), each stage from the last one's point, a homotopy from
a broad basin to the sharp minimum.  The states the recording does not measure beyond the piston's motion
(chamber pressures where it does not, an effect's own states: temperatures, spool, supply line) get a fraction
of the others' process noise (:data:`~.rules.UNMEASURED_FACTOR`): a filter free to move them explains a wrong
valve and friction by them, and an effect's states moved sample by sample stiffen the integration (a filter
pass over a heat-transfer model that lacked physics took minutes where it takes seconds held).  Measured
pressures keep theirs: the measurements hold them, and a filter that cannot follow them loses track of the
piston at the data sheet's values.  The friction smoothing
velocity is held in the broad stages (:data:`~.rules.HELD_BROAD`): a broad filter trades it for mistimed
slips.

The gradient holds the filter's gain fixed (the state sensitivities propagate through the model's
one-sample sensitivities and ``I - K H``); the least squares are SciPy's trust region on the whitened
innovations with that Jacobian.
"""
from __future__ import annotations

import queue
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.optimize import least_squares

from ..solver import work
from . import deadline
from .parameters import clip_inside
from .rules import (HELD_BROAD, HELD_UNTIL, PREDICTION_ERROR_EVALUATIONS,
                    PREDICTION_ERROR_TOLERANCE, PROCESS_SCHEDULE, SAME_PREFIT, UNMEASURED_FACTOR)
from .shooting import ShootingProblem
from .tracking import process_std, run_filter

__all__ = ["prediction_error_fit", "prediction_error_attempts", "PROCESS_SCHEDULE", "UNMEASURED_FACTOR"]


def prediction_error_fit(pb: ShootingProblem, theta0: np.ndarray, x_first: np.ndarray, lower: np.ndarray,
                         upper: np.ndarray, schedule=PROCESS_SCHEDULE, give_up_above: float = np.inf, sim=None,
                         after_first_stage=None, cancelled=None):
    """Least squares on the filter's whitened innovations over ``pb``'s window, from the scaled free
    parameters ``theta0`` and the first state ``x_first`` (SI), ``theta`` within ``lower .. upper``, the first
    state within :meth:`ShootingProblem.state_bounds`; one stage per process noise of ``schedule``, stopped
    after a stage that ends above ``give_up_above``.

    Why that stop: with less process noise the filter corrects less, and the innovations of a model that
    lacks physics only grow stage by stage, where those of a chaotic recording the model explains approach
    their noise level (``docs/decisions/0018``).

    ``sim`` (one of ``pb.sims``) integrates the filter, ``after_first_stage`` (if given) is called with the first
    stage's rms of the whitened innovations as soon as it ends, and the fit stops with
    :class:`~.tracking.FilterCancelled` once the event ``cancelled`` is set (:func:`prediction_error_attempts` runs
    several side by side).

    Returns ``(theta, x_first, info)``: the scaled parameters and first state (SI) of the last stage, and
    ``info`` with each stage's process noise, rms of the whitened innovations (1 where the model is right
    and the filter well tuned), passes and seconds, and the last stage's rms as ``"rms_innovations"``.
    """
    nf, n = pb.n_free, pb.n
    x_lo, x_hi = pb.state_bounds()
    lo = np.concatenate([lower, x_lo / pb.x_scale])
    hi = np.concatenate([upper, x_hi / pb.x_scale])
    w = clip_inside(np.concatenate([theta0, np.asarray(x_first, float) / pb.x_scale]), lo, hi)
    n_seen = max(1, sum(int(mask.sum()) for (_, _, _, _, mask) in pb.outputs))   # a gap's innovation is 0
    stages = []

    def stage_ended(stage: dict):
        stages.append(stage)
        if after_first_stage is not None and len(stages) == 1:
            after_first_stage(stage["rms_innovations"])

    for fraction in schedule:
        process = process_std(pb, fraction, UNMEASURED_FACTOR)
        cache = {}

        def evaluate(v):
            key = v.tobytes()
            if key not in cache:
                cache.clear()
                run = run_filter(pb, v[:nf], v[nf:] * pb.x_scale, process, gradients=True, sim=sim,
                                 cancelled=cancelled, stop_at_failure=True)
                if not run["ok"]:
                    # a point the model cannot be integrated at: no finite cost, the trust region shrinks
                    run["innovations"] = np.full_like(run["innovations"], np.inf)
                cache[key] = run
            return cache[key]

        started = time.perf_counter()
        if not np.all(np.isfinite(evaluate(w)["innovations"])):
            # the filter cannot run from this point at all: nothing to fit
            stage_ended({"process_std": fraction, "rms_innovations": float("inf"), "evaluations": 1,
                         "seconds": time.perf_counter() - started})
            break
        # the variables this stage moves: all but the held parameters in the broad stages
        moving = np.array([not (name in HELD_BROAD and fraction > HELD_UNTIL) for name in pb.free] + [True] * n)
        base = w.copy()

        def full(u):
            v = base.copy()
            v[moving] = u
            return v

        fit = least_squares(lambda u: evaluate(full(u))["innovations"], w[moving],
                            jac=lambda u: evaluate(full(u))["jacobian"][:, moving],
                            bounds=(lo[moving], hi[moving]), method="trf", x_scale=1.0,
                            max_nfev=PREDICTION_ERROR_EVALUATIONS, xtol=PREDICTION_ERROR_TOLERANCE,
                            ftol=PREDICTION_ERROR_TOLERANCE)
        w = full(fit.x)
        rms = float(np.sqrt(np.sum(fit.fun ** 2) / n_seen)) if np.all(np.isfinite(fit.fun)) else float("inf")
        stage_ended({"process_std": fraction, "rms_innovations": rms, "evaluations": int(fit.nfev),
                     "seconds": time.perf_counter() - started})
        if not rms <= give_up_above:
            break
    info = {"stages": stages, "rms_innovations": stages[-1]["rms_innovations"],
            "seconds": sum(s["seconds"] for s in stages)}
    return w[:nf], w[nf:] * pb.x_scale, info


def prediction_error_attempts(pb: ShootingProblem, starts, x_first: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                              give_up_above: float = np.inf, schedule=PROCESS_SCHEDULE, side_by_side: bool = True) -> list:
    """The prediction-error fit from several starts of the same parameters, the lowest end confirmed: ``starts``
    (scaled parameter vectors, the first the start itself, the others nearby; ``x_first`` the first state, SI).

    From the first start the whole ``schedule`` (:func:`prediction_error_fit`).  Unless its first stage ended above
    ``give_up_above`` (a model that lacks physics, which no start supplies): the first, broadest stage from each
    other start, then the rest of the schedule from those landings in the order of their innovations, lowest
    first, until a start ends within :data:`~.rules.SAME_PREFIT` (relative) of the lowest end so far (two starts
    agree on the lowest basin found), or every start has been continued.

    Why not stop at the first start that ends at the innovations' noise level: on a chaotic recording a start can
    end at the noise level in a wrong basin (whitened innovations 0.956, where the truth's basin gives 0.767 and
    the whole fit then reaches the noise with five of seven parameters beyond 3 standard errors), and which start
    does is a draw of the last bits of the arithmetic.  The lowest end, once a second start confirms it, is the
    same on every machine (``docs/decisions/0103``).

    The fits run side by side, one per simulator of ``pb`` (:class:`_SideBySide`): the other starts' first stages
    as soon as the first start's first stage has passed, and each continuation beside the next one in order,
    which is dropped where the first agrees.  Each fit integrates on a simulator of its own and is the same
    computation as one after the other, so the result is the same doubles; only the wall clock shortens (a
    filter pass integrates in one thread, and the shooting problem's threads idle meanwhile).  ``side_by_side``
    False runs them one after the other on the first simulator.
    """
    def fit(start, first, stages, **hooks):
        return prediction_error_fit(pb, start, first, lower, upper, stages, give_up_above, **hooks)

    with _SideBySide(pb if side_by_side else None) as side:
        landing_runs = []

        def others_first_stages(rms):
            if rms <= give_up_above:
                landing_runs.extend(side.submit(fit, start, x_first, schedule[:1]) for start in starts[1:])

        theta, first, info = side.submit(fit, starts[0], x_first, schedule,
                                         after_first_stage=others_first_stages).result()
        out = [(theta, first, {**info, "start": 0})]
        if not info["stages"][0]["rms_innovations"] <= give_up_above or len(starts) == 1:
            return out
        landings = [(k, *run.result()) for k, run in enumerate(landing_runs, 1)]
        lowest, order = info["rms_innovations"], sorted(landings, key=lambda landing: (landing[3]["rms_innovations"],
                                                                                       landing[0]))

        def continued(n):
            """The rest of the schedule from landing ``n`` of ``order``, None past a landing above give_up_above."""
            if n >= len(order) or not order[n][3]["rms_innovations"] <= give_up_above:
                return None
            return side.submit(fit, order[n][1], order[n][2], schedule[1:])

        ahead = continued(0)
        for n, (k, theta, first, landed) in enumerate(order):
            if not landed["rms_innovations"] <= give_up_above:
                out += [(None, None, {**rest[3], "start": rest[0]}) for rest in order[n:]]
                break
            run, ahead = ahead, continued(n + 1)
            theta, first, rest = run.result()
            out.append((theta, first, {"stages": landed["stages"] + rest["stages"], "start": k,
                                       "rms_innovations": rest["rms_innovations"],
                                       "seconds": landed["seconds"] + rest["seconds"]}))
            if abs(rest["rms_innovations"] / lowest - 1.0) < SAME_PREFIT:
                out += [(None, None, {**later[3], "start": later[0]}) for later in order[n + 1:]]
                break
            lowest = min(lowest, rest["rms_innovations"])
        return out


class _SideBySide:
    """Prediction-error fits run side by side, one per simulator of ``pb`` (``pb.sims``), in threads: a filter pass
    spends its time in CVODES, which runs without the GIL.  ``submit(fit, *args, **hooks)`` returns a run whose
    ``result()`` is ``fit(*args, sim=..., cancelled=..., **hooks)``; leaving the block cancels the runs whose result
    was not asked for (:class:`~.tracking.FilterCancelled` at their next sample) and waits for them, so that no
    thread integrates on ``pb`` afterwards.  With fewer than two simulators (or no problem) a run is computed when
    its result is asked for, in the caller's thread: the order of the calls one after the other."""

    def __init__(self, pb):
        sims = list(getattr(pb, "sims", None) or [])
        self._pool = ThreadPoolExecutor(len(sims)) if len(sims) > 1 else None
        self._free = queue.SimpleQueue()
        for sim in sims:
            self._free.put(sim)
        self._runs = []

    def submit(self, fit, *args, **hooks):
        cancelled = threading.Event()
        ledger = work.branch()   # a cancelled run's work counts nowhere: the count is its callers' logic's

        def run():
            if cancelled.is_set():
                return None
            sim = self._free.get()
            try:
                with work.on(ledger):
                    return fit(*args, sim=sim, cancelled=cancelled, **hooks)
            finally:
                self._free.put(sim)

        if self._pool is None:
            handle = _Deferred(lambda: fit(*args, **hooks))
        else:
            handle = _Taken(self._pool.submit(run), ledger)
        self._runs.append((handle, cancelled))
        return handle

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        for handle, cancelled in self._runs:
            cancelled.set()
        if self._pool is not None:
            self._pool.shutdown(wait=True)
        return False


class _Taken:
    """A run on another thread whose work counts where its result is taken (:func:`.deadline.take`)."""

    def __init__(self, future, ledger):
        self._future, self._ledger, self._taken = future, ledger, False

    def result(self):
        try:
            return self._future.result()
        finally:
            if not self._taken:
                self._taken = True
                deadline.take(self._ledger)


class _Deferred:
    """A run computed when its result is first asked for (:class:`_SideBySide` without threads)."""

    def __init__(self, compute):
        self._compute, self._done, self._value = compute, False, None

    def result(self):
        if not self._done:
            self._value, self._done = self._compute(), True
        return self._value
