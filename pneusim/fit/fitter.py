"""Fit the physical model to a recording: estimates, uncertainty, validation.

``fit_recording(recording, rig)`` runs, in order:

1. **checks** — the recording matches the rig (sample time, stroke, pressure
   range) and moves enough to say anything about the free parameters;
2. **split** — the first ``1 - validation_fraction`` of the recording
   estimates, the rest validates and is never seen by the optimiser;
3. **pre-fit** — the multiple-shooting problem (:mod:`.shooting`) on a short
   window (the estimation part's first samples, or where the piston moves when it rests through those:
   :meth:`.setup.FitSetup.prefit_start`), from the rig file's values, by trust-region least squares with the
   continuity between segments as a weighted residual; where that ends above noise and both
   pressures are recorded, also with the weight raised in turn, keeping the better route
   (:func:`.stages.prefit`), and through :data:`.stages.SHORT_SEGMENTS`-sample segments, kept when the
   pre-fit's own problem from there ends clearly lower (:func:`.routes.short_segments_route`);
4. **fit** — the whole estimation part from the pre-fit: trust region (where
   that ends above noise and well above the pre-fit, also with the continuity weight raised in turn:
   :func:`.stages.full_fit`), then the exact constrained problem: by Gauss-Newton steps where the trust
   region ended at noise, until the next step is within a tenth of every standard error
   (:func:`.stages.settled`), else (or where those do not settle) by IPOPT (:mod:`.nlp`); a fit that
   ends well above its pre-fit's residual, or above noise after a pre-fit above noise, is retried
   from the next start (the best kept; a start whose pre-fit ends where an earlier one's did is not
   fitted again), unless the pre-fit itself ends more than
   :data:`.stages.MODEL_SHORT` times above noise (the model lacks physics there);
   where the best fit still ends above noise, but neither it nor every pre-fit more than
   :data:`.stages.MODEL_SHORT` times above it: every segment started from the state an extended
   Kalman filter tracks at that fit's parameters (:mod:`.tracking`), the trust region with the
   continuity weight raised in turn, then IPOPT, kept when lower (:func:`.routes.tracked_route`;
   ``solver["tracked_route"]``); where it still ends above noise (however far): least squares on the
   innovations of that filter from the start (:mod:`.prediction_error`), a landscape smooth where the
   shooting problem's is rippled by every stick-slip, then the same tracked route from there, kept when
   lower (:func:`.routes.prediction_error_route`; ``solver["prediction_error_route"]``);
5. **uncertainty** — the Gauss-Newton covariance of the estimates with the
   segment states as nuisance parameters, each signal weighted by its residual
   standard deviation (:mod:`.uncertainty`); standard errors, correlations and
   warnings for parameters the recording cannot pin down;
6. **validation** — the fitted model simulated over the validation part with
   the recorded command, from the state the fit estimated at its start, and
   scored with MATLAB's fit %;
7. **noise check** — the residual rms of each measured signal over its sensor
   noise (:attr:`FitResult.normalised_residual`); above 1.1 the result says
   ``converged_to_noise = False``, ``solver["success"] = False`` and warns.

``warm_start=`` (a fit of the same recording) skips 3. and starts 4. from that
fit's parameters and states: diagnosis's refits with one more effect.
"""

from __future__ import annotations

import logging
import sys
import time
from typing import Sequence

import numpy as np

from ..errors import FitError
from ..metrics import fit_percent
from ..model import Effect
from ..recording import Recording
from ..rig import Rig
from ..solver.sensitivity import command_schedule
from .initial import better_first_state, initial_starts
from .result import ABOVE_NOISE_WARNING, FitResult, ParameterEstimate
from .setup import FitSetup, _name
from .shooting import ShootingProblem, position_reading
from .routes import prediction_error_route, short_segments_route, tracked_route
from .stages import MODEL_SHORT, PENALTY_WEIGHT, SHORT_SEGMENTS, full_fit, polish, prefit, settled, trust_region, well_above
from .threads import one_blas_thread
from .uncertainty import covariance
from .warm_start import warm_states

__all__ = ["fit_recording"]

_LOG = logging.getLogger("pneusim.fit")

#: alternative starts of the pre-fit, as factors on the starting values (deterministic)
_START_FACTORS = (
    {},
    {"valve_sonic_conductance_m3_per_s_Pa": 0.6, "friction_static_N": 0.6, "friction_coulomb_N": 0.6,
     "moving_mass_kg": 1.5},
    {"valve_sonic_conductance_m3_per_s_Pa": 1.6, "friction_static_N": 1.8, "friction_coulomb_N": 1.8,
     "friction_viscous_N_s_per_m": 0.5, "moving_mass_kg": 0.7},
)

#: a restart's pre-fit ending within this relative distance of an earlier start's is the same basin:
#: practice2_30's three pre-fits ended within 4.5e-4 of each other and all three fits at 1.63-1.64;
#: a paper-1 recording's first two 0.9 % apart (2.700, 2.725) had fits at 4.29 and 3.10
SAME_PREFIT = 1e-3


@one_blas_thread
def fit_recording(recording: Recording, rig: Rig | str | None = None, effects: Sequence[Effect] = (),
                  free: Sequence[str] | None = None, *, validation_fraction: float | None = None,
                  segment_samples: int = 50, prefit_samples: int = 2000, starts: int = 3,
                  rtol: float = 1e-6, threads: int = 2, max_iter: int = 40, verbose: bool = False,
                  quiet: bool = False, warm_start: FitResult | None = None,
                  start_values: dict | None = None) -> FitResult:
    """Fit the rig's uncertain parameters (and those of ``effects``) to ``recording``.

    Parameters
    ----------
    recording : Recording
        A ``pneusim-recording/1`` recording (position, command, optionally pressures).
    rig : Rig, str or None
        The nominal rig (starting values and known data); default the
        recording's ``rig`` metadata.
    effects : sequence of Effect
        Optional physics switched on in the model; their parameters are
        starting values and are freed too (unless ``free`` says otherwise).
    free : sequence of str, optional
        Names of the free parameters; default :data:`DEFAULT_FREE` plus the
        effects' parameters.
    validation_fraction : float, optional
        Final fraction of the recording kept for validation, in (0, 0.9]; default 0.3, or with
        ``warm_start`` that fit's own split (a refit must fit the same estimation part).
    segment_samples : int
        Samples per shooting segment.
    prefit_samples : int
        Length of the pre-fit window, samples (``solver["prefit_attempts"][k]["window_start_sample"]`` says
        where it began).
    starts : int
        Pre-fit starts tried at most (the first from the rig file's values).
    rtol : float
        CVODES relative tolerance.
    threads : int
        Threads integrating segments in parallel.
    max_iter : int
        IPOPT iterations per polishing round.
    quiet : bool
        Print nothing.  By default one line per stage (pre-fit, trust region, IPOPT, uncertainty,
        validation) goes to standard error with its time and normalised residual; the same lines go
        to the ``logging`` logger ``pneusim.fit`` at INFO level either way.
    verbose : bool
        Kept for compatibility: ``verbose=True`` prints the stage lines even with ``quiet``.
    warm_start : FitResult, optional
        A fit of the **same recording** (same estimation part) to start from, typically the nominal
        fit when diagnosis refits with one more effect::

            nominal = fit_recording(rec, rig, quiet=True)
            refit = fit_recording(rec, rig, effects=[make_effect("valve_deadband")],
                                  warm_start=nominal, quiet=True)

        Starting values: every parameter the warm fit had takes its fitted value (free or fixed
        now); new effect parameters start at the effect's given values.  Segment start states: the
        warm fit's estimated states at every sample (so segment lengths may differ); states the warm
        model lacks (spool, temperatures, supply pressure) start from the model's equilibrium
        (:meth:`ActuatorModel.initial_state`) at that sample's position and command.  The pre-fit
        and the alternative starts are skipped: the trust region and IPOPT start there directly.
        Scales and bounds stay those of ``rig``'s data-sheet values, so a warm and a cold fit
        solve the same problem.  ``solver["warm_start"]`` is True in the result.
    start_values : dict, optional
        ``{parameter name: value in SI units}`` to start from instead of the rig's (or the warm
        fit's) values, e.g. friction levels that belong with a new effect's starting value.

    Raises
    ------
    FitError
        The recording does not match the rig, does not excite the free
        parameters, or the optimiser could not fit it.
    """
    started = time.perf_counter()
    say = _Progress(quiet and not verbose, started)
    if validation_fraction is None and warm_start is not None:
        # the warm fit's split: round(n * (n_est / n)) gives back n_est exactly
        validation_fraction = 1.0 - warm_start.n_estimation / recording.n_samples
    setup = FitSetup(recording, rig, effects, free, validation_fraction, warm_start, start_values, segment_samples)
    rig, model, free, delay_s = setup.rig, setup.model, setup.free, setup.delay_s
    p_start, index, scales, bounds = setup.p_start, setup.index, setup.scales, setup.bounds
    lower, upper, theta_start, n_est, seg = setup.lower, setup.upper, setup.theta_start, setup.n_est, setup.seg
    sigma = setup.sigma

    def problem(stop, segment=None, start=0):
        return setup.problem(stop, rtol, threads, segment, start)

    pb, lo, hi = problem(n_est)

    def finish(v):
        """IPOPT on the whole estimation part from ``v``: ``(result, normalised rms)``."""
        done = polish(pb, v, lo, hi, max_iter, rtol, penalty=PENALTY_WEIGHT)
        return done, _normalised_rms(pb, done)

    attempts, fits = [], []
    if warm_start is not None:
        # a refit: no pre-fit, no alternative starts; trust region and IPOPT from the warm point
        x_init = warm_states(warm_start, pb, p_start, recording)
        # near the optimum already: the trust region only has to bring the new effect in; it stops at a
        # relative cost change of 1e-3 (not 1e-4) and IPOPT finishes the exact problem
        v_ls, rms_ls, info = trust_region(pb, pb.join(theta_start, x_init), lo, hi, defect_weight=PENALTY_WEIGHT,
                                          tolerance=1e-3)
        say(f"warm start: trust region {info['status']} after {info['evaluations']} evaluations "
            f"({info['seconds']:.1f} s), normalised rms residual {rms_ls:.3g}")
        res = polish(pb, v_ls, lo, hi, max_iter, rtol, penalty=PENALTY_WEIGHT)
        rms = _normalised_rms(pb, res)
        say(f"warm start: IPOPT {res.status} after {res.iterations} iterations ({res.seconds:.1f} s), "
            f"normalised rms residual {rms:.3g}")
        if res.status == "Maximum_Iterations_Exceeded" and rms > ABOVE_NOISE_WARNING and rms < 0.75 * rms_ls:
            # stopped by the iteration cap, not converged, while the new effect is still coming in (a -100 N
            # load refitted from a nominal fit at 55 times noise: 34.7 -> 19.7 in 40 iterations, validation
            # 90 %): one more round from there, kept when it lowers the residual; not where IPOPT has
            # stalled (a wrong candidate creeping along costs a whole round for nothing)
            more = polish(pb, res.v, lo, hi, max_iter, rtol, penalty=PENALTY_WEIGHT)
            if np.isfinite(more.objective) and more.objective < res.objective:
                more.iterations += res.iterations
                more.seconds += res.seconds
                res = more
                rms = _normalised_rms(pb, res)
            say(f"warm start: IPOPT continued to {res.iterations} iterations, normalised rms residual {rms:.3g}")
        attempts.append({"start": "warm", "fit_rms_normalised": rms, "ipopt_status": res.status,
                         "ipopt_iterations": res.iterations, **info})
        fits.append((res.objective if np.isfinite(res.objective) else np.inf, 0, res))
    else:
        # pre-fit on a short window from a start, then the whole estimation part from the pre-fit: trust
        # region first, then IPOPT on the exact constrained problem.  A short window can leave two basins
        # equally good (the valve's critical pressure ratio against its conductance, say) that the whole
        # part tells apart: a fit that ends well above its pre-fit's residual is retried from the next start.
        # the window: the estimation part's first samples, unless the piston hardly moves there
        pre_start = setup.prefit_start(prefit_samples)
        pre_stop = pre_start + min(n_est, prefit_samples)
        window = recording if pre_start == 0 else recording.slice(recording.time_s[pre_start],
                                                                  recording.time_s[pre_stop])
        where = "" if pre_start == 0 else f" from sample {pre_start}, where the piston moves"
        pre_pb, pre_lo, pre_hi = problem(pre_stop, start=pre_start)
        for k, factors in enumerate(_START_FACTORS[:max(1, starts)]):
            theta0 = np.clip(theta_start * np.array([factors.get(name, 1.0) for name in free]), lower, upper)
            chained = initial_starts(pre_pb, theta0, window, pre_pb.data.n_samples)
            if k == 0 and pre_start == 0:
                first_at_start = chained[0]   # the prediction-error route starts from here too
            v0 = pre_pb.join(theta0, chained)
            v_pre, rms_pre, info = prefit(pre_pb, v0, pre_lo, pre_hi)
            attempts.append({"start": k + 1, "rms_normalised": rms_pre, "window_start_sample": pre_start, **info})
            say(f"start {k + 1}, pre-fit ({pre_pb.data.n_samples} samples{where}): trust region {info['status']} after "
                f"{info['evaluations']} evaluations ({info['seconds']:.1f} s), normalised rms residual {rms_pre:.3g}"
                + _routes_text(info))
            same = [a["start"] for a in attempts[:-1] if abs(rms_pre / a["rms_normalised"] - 1.0) < SAME_PREFIT]
            if same:
                # the window's same basin: the whole part's fit from there is known (practice2_30, heat
                # transfer left out: all three pre-fits ended at 1.49 and all three fits at 1.63-1.64,
                # 85 s; skipping the fits of starts 2 and 3, 34 s)
                attempts[-1]["fit_skipped"] = f"pre-fit ended where start {same[0]}'s did"
                say(f"start {k + 1}: the pre-fit ended where start {same[0]}'s did ({rms_pre:.3g}), the same basin: "
                    "not fitted again")
                continue
            if recording.has_pressures and ABOVE_NOISE_WARNING < rms_pre <= MODEL_SHORT:
                v_pre, rms_pre, route = short_segments_route(problem(pre_stop, SHORT_SEGMENTS, start=pre_start), pre_pb,
                                                             pre_lo, pre_hi, theta0, v_pre, rms_pre, window)
                attempts[-1]["short_segments"] = route
                say(f"short segments ({SHORT_SEGMENTS} samples): pre-fit {route['rms_short_normalised']:.3g}, then "
                    f"{route['rms_normalised']:.3g} on the pre-fit's segments against "
                    f"{attempts[-1]['rms_normalised']:.3g}: {'kept' if route['kept'] else 'not kept'} "
                    f"({route['seconds']:.1f} s)")
            theta0, prefit_states = pre_pb.split(v_pre)
            x_init = initial_starts(pb, theta0, recording, n_est)
            fresh_first = x_init[0].copy()
            # the pre-fit's own segment states where its window is the part's start; a window moved to where the
            # piston moves begins at rest, with chamber pressures the window barely says anything about, and
            # the states chained from the recording's start are kept throughout (the robustness set's s1043,
            # no pressures recorded: with the window's states the mass ended 4.8 standard errors off, 0.7 without)
            for j, first in enumerate(pb.starts.tolist() if pre_start == 0 else []):
                if first in pre_pb.starts and first < pre_pb.starts[-1]:
                    x_init[j] = prefit_states[list(pre_pb.starts).index(first)]
            x_init[0] = better_first_state(pb, theta0, [x_init[0], fresh_first])
            v_ls, rms_ls, info = full_fit(pb, pb.join(theta0, x_init), lo, hi, rms_pre, finish=finish)
            say(f"start {k + 1}, fit ({n_est} samples): trust region {info['status']} after {info['evaluations']} "
                f"evaluations ({info['seconds']:.1f} s), normalised rms residual {rms_ls:.3g}" + _routes_text(info))
            # IPOPT on the kept route's point, unless the direct route's was already finished and kept; where
            # the continuation was kept over a finished direct route, the better of the two finished fits
            finished = info.pop("finished", None)
            done = settled(pb, v_ls, rms_ls, rtol, lo, hi) if finished is None else None
            if done is not None:
                res, rms = done, _normalised_rms(pb, done)
            else:
                res, rms = finished if finished is not None and info["route"] == "direct" else finish(v_ls)
            if finished is not None and info["route"] != "direct" and finished[0].objective < res.objective:
                res, rms = finished
            attempts[-1].update(fit_rms_normalised=rms, fit_routes=info["routes"], ipopt_status=res.status,
                                ipopt_iterations=res.iterations)
            fits.append((res.objective if np.isfinite(res.objective) else np.inf, k, res))
            how = (f"settled by {res.iterations} Gauss-Newton steps on the constrained problem (largest defect "
                   f"{res.max_defect:.2g}, the next step within a tenth of every standard error; IPOPT not needed)"
                   if done is not None else
                   f"IPOPT {res.status} after {res.iterations} iterations ({res.seconds:.1f} s)")
            say(f"start {k + 1}, fit: {how}, normalised rms residual {rms:.3g}")
            # restart when the fit ended well above its pre-fit (the short window had a second basin)
            # or when both ended above noise: the window's basin need not be the whole part's (paper 1,
            # closed-loop multisine without pressures: start 1's pre-fit 2.14 and fit 2.37 times noise
            # with the Stribeck velocity at 3.4 times the truth; start 2's pre-fit 2.99, fit 0.996)
            if not (well_above(rms, rms_pre) or min(rms, rms_pre) > ABOVE_NOISE_WARNING):
                break
            if rms_pre > MODEL_SHORT:
                # the restart is for a short window's second basin; a pre-fit this far above noise says
                # the model lacks physics on this recording, which no other start supplies (on
                # diagnosis's -100 N load recording three starts ended at 58.3, 55.3, 54.8 in 150 s, and
                # the refit with the load reaches the noise from the first as from the third)
                say(f"start {k + 1}: not restarting, the pre-fit itself ends {rms_pre:.3g} times above noise "
                    f"(more than {MODEL_SHORT:g}): the model lacks physics here")
                break
    res = min(fits, key=lambda f: (f[0], f[1]))[2]
    rms_best = _normalised_rms(pb, res)
    tracked = None
    if (warm_start is None and ABOVE_NOISE_WARNING < rms_best <= MODEL_SHORT
            and min(a["rms_normalised"] for a in attempts) <= MODEL_SHORT):
        # the fit ended above noise, but neither it nor every pre-fit so far above that the model lacks
        # physics: segment starts tracked by a Kalman filter at its parameters, for a recording too chaotic
        # for chained starts.  (The nominal fits of practice2's 30 recordings: tried on 8, 3-57 s each, kept
        # on a control with nothing missing, 1.75 -> 1.49, and on one at 5.49 -> 5.489; two of the eight,
        # at 5.49 and 5.94, more than MODEL_SHORT above noise, are no longer tried.)
        res, tracked = _better(res, *tracked_route(pb, res.v, lo, hi, rms_best, finish))
        say("tracked starts: " + _rounds_text(tracked)
            + f" against {rms_best:.3g}: {'kept' if tracked['kept'] else 'not kept'} ({tracked['seconds']:.1f} s)")
    predicted = None
    if warm_start is None and _normalised_rms(pb, res) > ABOVE_NOISE_WARNING:
        # still above noise, however far: the prediction-error route from the start, for a recording too
        # chaotic for the shooting problem's landscape (s1030 of the robustness set: every pre-fit more than
        # MODEL_SHORT above noise in a wrong basin, 9.7 -> 0.99 through this route);
        # the filter tells apart a chaotic recording from one the model lacks physics for: the route stops
        # where its innovations end far above their noise level (see prediction_error_route)
        if pre_start > 0:
            # the route tracks the whole part from its start: its window is the recording's first samples
            pre_pb.close()
            pre_pb, _, _ = problem(min(n_est, prefit_samples))
            first_at_start = initial_starts(pre_pb, theta_start, recording, pre_pb.data.n_samples)[0]
        res, predicted = _better(res, *prediction_error_route(pre_pb, pb, lo, hi, theta_start, first_at_start,
                                                              _normalised_rms(pb, res), finish))
        pem = predicted["prediction_error"]
        say(f"prediction-error route: filter innovations {pem['rms_innovations']:.3g} ({pem['seconds']:.1f} s)"
            + (", tracked starts " + _rounds_text(predicted) if "rounds" in predicted else "")
            + f": {'kept' if predicted['kept'] else 'not kept'} ({predicted['seconds']:.1f} s)")
    if warm_start is None:
        pre_pb.close()
    if not np.isfinite(res.objective):
        pb.close()
        raise FitError(f"{_name(recording)}: the model could not be integrated at the optimiser's last point "
                       f"(IPOPT: {res.status}); check the rig file and the effects")
    theta, _ = pb.split(res.v)
    estimate = pb.params_of(theta)
    uncertainty = covariance(pb, res.v)
    # the continuity defects left open at the optimum (state-scaled): a fit that ended in the penalty form
    # bought part of its residual with them, which a comparison of residuals alone would reward
    defects = pb.evaluate(res.v, derivatives=False)["g"]
    defect_sum_squares = float(np.dot(defects, defects)) if np.all(np.isfinite(defects)) else float("inf")
    pb.close()
    say("uncertainty: Gauss-Newton covariance done")
    x_boundary = uncertainty["states"][n_est - 1].copy()
    validation = _validate(model, estimate, recording, n_est, x_boundary, delay_s, rig.stroke_m, rtol)
    parameters = {}
    for k, name in enumerate(free):
        lo_b, hi_b = bounds[k]
        parameters[name] = ParameterEstimate(
            # IPOPT may end a hair outside a bound (its bound_relax_factor): report the bound itself, so
            # a physical range check never refuses a fitted value such as a static friction of -4e-7 N
            name=name, estimate=float(np.clip(estimate[index[k]], lo_b, hi_b)), std=float(uncertainty["std"][k] * scales[k]),
            start=float(p_start[index[k]]), lower=float(lo_b), upper=float(hi_b))
    result = FitResult.build(
        recording=recording, rig=rig, model=model, free=free, parameters=parameters,
        correlation=uncertainty["correlation"][:len(free), :len(free)], params_vector=estimate,
        n_estimation=n_est, sigma=uncertainty["sigma"], noise_std=sigma,
        validation=validation, solver={"status": res.status, "ipopt_success": res.success,
                                       "iterations": res.iterations,
                                       "seconds": time.perf_counter() - started, "ipopt_seconds": res.seconds,
                                       "max_defect": res.max_defect, "defect_sum_squares": defect_sum_squares,
                                       "prefit_attempts": attempts, "tracked_route": tracked,
                                       "prediction_error_route": predicted,
                                       "formulation": res.formulation, "warm_start": warm_start is not None,
                                       "segments": int(pb.n_segments), "segment_samples": seg},
        estimation_states=uncertainty["states"])
    say(f"done in {result.solver['seconds']:.1f} s: validation fit {result.fit_percent:.2f} %, normalised "
        f"residual {result.normalised_residual:.3g} (noise level 1)"
        + ("" if result.converged_to_noise else " -- ABOVE NOISE, see the warnings"))
    return result


class _Progress:
    """One line per fit stage: to the ``pneusim.fit`` logger, and to standard error unless quiet."""

    def __init__(self, quiet: bool, started: float):
        self.quiet, self.started = quiet, started

    def __call__(self, message: str) -> None:
        line = f"fit [{time.perf_counter() - self.started:6.1f} s] {message}"
        _LOG.info(line)
        if not self.quiet:
            print(line, file=sys.stderr, flush=True)


def _better(res, done, info: dict):
    """``(fit, info)``: a route's finished fit ``done`` where it is finite and lower than ``res`` (its
    iterations and seconds counted on top of ``res``'s), else ``res``; ``info["kept"]`` says which."""
    info["kept"] = bool(done is not None and np.isfinite(done.objective) and done.objective < res.objective)
    if not info["kept"]:
        return res, info
    done.iterations += res.iterations
    done.seconds += res.seconds
    return done, info


def _rounds_text(info: dict) -> str:
    """A tracked route's rounds and its finished residual, for the stage line."""
    finished = info.get("finished_rms_normalised")
    return (", ".join(f"{r['rms_normalised']:.3g}" for r in info["rounds"])
            + (f", IPOPT {finished:.3g}" if finished is not None else ""))


def _normalised_rms(pb: ShootingProblem, res) -> float:
    """The normalised rms residual of an IPOPT result (noise level 1)."""
    return float(np.sqrt(res.objective / max(pb.n_residuals, 1)))


def _routes_text(info: dict) -> str:
    """The routes a :func:`.stages.two_routes` stage tried and the one it kept, for the stage line."""
    if len(info["routes"]) < 2 and "finished_rms_normalised" not in info["routes"][0]:
        return ""
    routes = ", ".join(f"{r['route']} {r['rms_normalised']:.3g}"
                       + (f" (IPOPT from it {r['finished_rms_normalised']:.3g})" if "finished_rms_normalised" in r else "")
                       for r in info["routes"])
    skipped = info["routes"][0].get("second_route_skipped")
    return f" (routes: {routes}; kept {info['route']}" + (f"; continuation not tried: {skipped})" if skipped else ")")


def _validate(model, params, recording: Recording, n_est: int, x0, delay_s, stroke_m, rtol) -> dict:
    """Simulate the validation part with the recorded command from the fitted boundary state."""
    from ..solver.sensitivity import SensitivitySimulator

    sim = SensitivitySimulator(model, [], params, np.zeros(0), stroke_m, rtol)
    start, stop = n_est - 1, recording.n_samples - 1
    schedule = command_schedule(recording.time_s, recording.valve_cmd_V, start, stop, delay_s)
    x, _ = sim.run(recording.time_s[start], x0, schedule, stop - start + 1, False)
    x = x[1:]
    y = recording.position_m[n_est:]
    out = {"t_start_s": float(recording.time_s[n_est]), "t_end_s": float(recording.time_s[-1]),
           "fit_percent": fit_percent(y, position_reading(x[:, 0], stroke_m)), "states": x}
    for name in ("pressure_a_Pa", "pressure_b_Pa"):
        values = getattr(recording, name)
        if values is not None:
            out[f"fit_percent_{name}"] = fit_percent(values[n_est:], x[:, model.state_names.index(name)])
    return out
