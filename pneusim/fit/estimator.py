"""The physical fit as an estimator with swappable stages: :class:`PhysicalFit` and :class:`FitStages`.

``PhysicalFit(rig, effects, free, ...).fit(recording)`` runs, in order:

1. **checks and split** — the recording matches the rig (sample time, stroke, pressure range) and moves
   enough to say anything about the free parameters; the first ``1 - validation_fraction`` of it
   estimates, the rest validates and is never seen by the optimiser (:class:`.setup.FitSetup`);
2. **pre-fit from each start** — the multiple-shooting problem (:mod:`.shooting`) on a short window (the
   estimation part's first samples, or where the piston moves when it rests through those:
   :meth:`.setup.FitSetup.prefit_start`), from the rig file's values, by trust-region least squares with the
   continuity between segments as a weighted residual (:func:`.stages.prefit`); where that ends above noise
   and both pressures are recorded, also through short segments (:func:`.rescue_routes.short_segments_route`);
3. **whole fit** — the whole estimation part from the pre-fit: trust region (:func:`.stages.full_fit`), then
   the exact constrained problem: by Gauss-Newton steps where the trust region ended at noise
   (:func:`.constrained.settle_gauss_newton`), else (or where those do not settle) by IPOPT
   (:func:`.constrained.solve_ipopt_exact`).  A fit that ends well above its pre-fit's residual, or above
   noise after a pre-fit above noise, is retried from the next start (:data:`.rules.START_FACTORS`; the best
   kept; a start whose pre-fit ends where an earlier one's did is not fitted again), unless the pre-fit
   itself ends more than :data:`.rules.MODEL_SHORT` times above noise (the model lacks physics there).  Where
   the first start's fit ends above noise, the prediction-error route (4.) runs before the next start, and no
   other start is tried where it brings the fit to noise;
4. **rescue routes** — where the best fit still ends above noise, but neither it nor every pre-fit more than
   :data:`.rules.MODEL_SHORT` times above it: segment starts tracked by an extended Kalman filter
   (:func:`.rescue_routes.tracked_route`, ``solver["tracked_route"]``), from the best fit's point and, until one
   reaches noise, from the other points the starts reached (:data:`.rules.TRACKED_STARTS`); where it still ends
   above noise (however far) and it has not run yet: the prediction-error fit from the start and from nearby
   starts until two agree on the lowest end (where the filter lands is a draw of the last bits of its
   arithmetic), then those tracked starts (:func:`.rescue_routes.prediction_error_route`,
   ``solver["prediction_error_route"]``); each kept when lower.  A route's fit is finished on the exact
   problem by Gauss-Newton settling where it ends at noise, else by IPOPT (:meth:`.run.FitRun.finish`);
5. **uncertainty** — the Gauss-Newton covariance of the estimates with the segment states as nuisance
   parameters, each signal weighted by its residual standard deviation (:mod:`.uncertainty`);
6. **validation** — the fitted model simulated over the validation part with the recorded command, from the
   state the fit estimated at its start, scored with MATLAB's fit % (:mod:`.validation`);
7. **result** — estimates, standard errors, correlations, warnings, and the noise check: the residual rms
   of each measured signal over its sensor noise; above :data:`.rules.ABOVE_NOISE_WARNING` the result says
   ``converged_to_noise = False``, ``solver["success"] = False`` and warns (:class:`.result.FitResult`): the
   verdict is what the fit reached, whichever optimiser finished it and however it stopped
   (``solver["stopped_by"]``).

``warm_start=`` (a fit of the same recording) skips 2. and 4.: the trust region and IPOPT start from that
fit's parameters and states (diagnosis's refits with one more effect).  The stages are the fields of
:class:`FitStages`; the thresholds that pick the path are in :mod:`.rules`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..errors import FitError
from ..model import Effect
from ..recording import Recording
from ..rig import Rig
from .constrained import settle_gauss_newton, solve_ipopt_exact
from .initial import better_first_state, initial_starts
from .stage_lines import rounds_text, routes_text
from .rescue_routes import prediction_error_route, short_segments_route, tracked_route
from .result import FitResult, ParameterEstimate
from .run import FitRun, better, normalised_rms, stopped_by
from .rules import (ABOVE_NOISE_WARNING, IPOPT_MAX_ITER, MODEL_SHORT, PENALTY_WEIGHT, PREFIT_SAMPLES, PREFIT_STARTS,
                    SAME_PREFIT, SEGMENT_SAMPLES, SHORT_SEGMENTS, START_FACTORS, TRACKED_STARTS,
                    WARM_CONTINUE_BELOW, WARM_TOLERANCE)
from .setup import FitSetup, _name
from .stages import full_fit, prefit, well_above
from .threads import one_blas_thread
from .trust_region import trust_region
from .uncertainty import covariance
from .validation import validate
from .warm_start import warm_states

__all__ = ["PhysicalFit", "FitStages"]


@dataclass(frozen=True)
class FitStages:
    """The stages of :class:`PhysicalFit`, each a callable, today's by default.  Pass others to study or test
    one stage alone, e.g. ``FitStages(settle=lambda *args: None)`` finishes every fit by IPOPT.

    Attributes
    ----------
    prefit : ``(pb, v0, lower, upper) -> (v, rms, info)``
        The pre-fit's trust region on the window (:func:`.stages.prefit`).
    short_segments : ``(short, pb, lower, upper, theta0, v, rms, window) -> (v, rms, info)``
        The pre-fit's short-segment route (:func:`.rescue_routes.short_segments_route`).
    whole_fit : ``(pb, v0, lower, upper, prefit_rms, finish=) -> (v, rms, info)``
        The whole estimation part's trust region (:func:`.stages.full_fit`).
    settle : ``(pb, v, rms, rtol, lower, upper) -> IpoptResult or None``
        Gauss-Newton on the exact problem where the trust region ended at noise
        (:func:`.constrained.settle_gauss_newton`); None hands over to ``finish``.
    finish : ``(pb, v, lower, upper, max_iter, rtol, penalty=) -> IpoptResult``
        IPOPT on the exact problem (:func:`.constrained.solve_ipopt_exact`).
    warm_trust_region : ``(pb, v0, lower, upper, defect_weight=, tolerance=) -> (v, rms, info)``
        A warm refit's trust region (:func:`.trust_region.trust_region`).
    tracked : ``(pb, v, lower, upper, rms, finish) -> (IpoptResult or None, info)``
        The tracked-starts route (:func:`.rescue_routes.tracked_route`).
    prediction_error : ``(window, pb, lower, upper, theta0, x_first, rms, finish) -> (IpoptResult or None, info)``
        The prediction-error route (:func:`.rescue_routes.prediction_error_route`).
    uncertainty : ``(pb, v) -> dict``
        Standard errors, correlations, residual stds and states (:func:`.uncertainty.covariance`).
    validate : ``(model, params, recording, n_est, x0, delay_s, stroke_m, rtol) -> dict``
        The validation part's simulation and fit % (:func:`.validation.validate`).
    """

    prefit: Callable = prefit
    short_segments: Callable = short_segments_route
    whole_fit: Callable = full_fit
    settle: Callable = settle_gauss_newton
    finish: Callable = solve_ipopt_exact
    warm_trust_region: Callable = trust_region
    tracked: Callable = tracked_route
    prediction_error: Callable = prediction_error_route
    uncertainty: Callable = covariance
    validate: Callable = validate


class PhysicalFit:
    """The physical fit of a rig's uncertain parameters (and those of ``effects``) to a recording.

    The constructor only stores the options (see :func:`~pneusim.fit.fit_recording` for each);
    :meth:`fit` fits one recording.  ``stages`` (:class:`FitStages`) holds the stage callables.

    Examples
    --------
    >>> fit = PhysicalFit(rig, quiet=True).fit(recording)                              # doctest: +SKIP
    >>> ipopt_only = PhysicalFit(rig, stages=FitStages(settle=lambda *a: None))        # doctest: +SKIP
    """

    def __init__(self, rig: Rig | str | None = None, effects: Sequence[Effect] = (), free: Sequence[str] | None = None,
                 *, validation_fraction: float | None = None, segment_samples: int = SEGMENT_SAMPLES,
                 prefit_samples: int = PREFIT_SAMPLES, starts: int = PREFIT_STARTS, rtol: float = 1e-6,
                 threads: int = 2, max_iter: int = IPOPT_MAX_ITER, quiet: bool = False, verbose: bool = False,
                 rescue: bool = True, stages: FitStages = FitStages()):
        self.rig, self.effects, self.free, self.rescue = rig, effects, free, rescue
        self.validation_fraction, self.segment_samples = validation_fraction, segment_samples
        self.prefit_samples, self.starts, self.rtol, self.threads = prefit_samples, starts, rtol, threads
        self.max_iter, self.quiet, self.verbose, self.stages = max_iter, quiet, verbose, stages

    @one_blas_thread
    def fit(self, recording: Recording, warm_start: FitResult | None = None,
            start_values: dict | None = None) -> FitResult:
        """Fit ``recording``: checks and split, pre-fit from each start, whole fit, rescue routes, uncertainty,
        validation, result (``warm_start``: a refit from that fit of the same recording, no pre-fit and no
        rescue).  Raises :class:`FitError` like :func:`~pneusim.fit.fit_recording`."""
        run = FitRun(self, recording, warm_start, start_values)                 # checks and split
        try:
            if warm_start is None:
                best = self._fit_from_starts(run)                             # pre-fit and whole fit, each start
                best = self._rescue(run, best)                                # rescue routes
            else:
                best = self._refit_warm(run, warm_start)                      # whole fit from the warm fit
            estimate, uncertainty = self._uncertainty(run, best)
            validation = self._validation(run, estimate, uncertainty)
            return self._build_result(run, best, estimate, uncertainty, validation)
        finally:
            run.close()

    # ------------------------------------------------------------------ pre-fit and whole fit from each start
    def _fit_from_starts(self, run: "FitRun"):
        """Each start's pre-fit, then the whole part from it, until a fit needs no restart; the best fit.

        A short window can leave two basins equally good (the valve's critical pressure ratio against its
        conductance, say) that the whole part tells apart: a fit that ends well above its pre-fit's residual
        is retried from the next start (``docs/decisions/0013``).  Where the first start's fit ends above noise,
        the prediction-error route runs before the next start, which is tried only where that route does not
        bring the fit to noise (``docs/decisions/0103``)."""
        setup = run.setup
        run.open_window(self.prefit_samples)
        for k, factors in enumerate(START_FACTORS[:max(1, self.starts)]):
            theta0 = np.clip(setup.theta_start * np.array([factors.get(name, 1.0) for name in setup.free]),
                             setup.lower, setup.upper)
            pre = self._prefit(run, k, theta0)
            if pre is None:
                continue
            rms_pre, rms = pre[1], self._whole_fit(run, k, *pre)
            if self.rescue and k == 0 and rms > ABOVE_NOISE_WARNING:
                # the prediction-error route before the other starts: where the first start fails on a recording
                # too chaotic for the shooting problem's landscape, the others fail there too (0103)
                if normalised_rms(run.pb, self._prediction_error(run, _best(run))) <= ABOVE_NOISE_WARNING:
                    break
            if not self._restart(run, k, rms, rms_pre):
                break
        return _best(run)

    def _prefit(self, run: "FitRun", k: int, theta0):
        """Start ``k``'s pre-fit from ``theta0`` on the window, and its short-segment route where that applies:
        ``(v, rms)``, or None where it ended where an earlier start's did (the same basin: not fitted again)."""
        pb, lo, hi = run.window
        chained = initial_starts(pb, theta0, run.window_recording, pb.data.n_samples)
        if k == 0 and run.window_start == 0:
            run.first_at_start = chained[0]   # the prediction-error route starts from here too
        v_pre, rms_pre, info = self.stages.prefit(pb, pb.join(theta0, chained), lo, hi)
        attempt = {"start": k + 1, "rms_normalised": rms_pre, "window_start_sample": run.window_start, **info}
        run.attempts.append(attempt)
        where = "" if run.window_start == 0 else f" from sample {run.window_start}, where the piston moves"
        run.say(f"start {k + 1}, pre-fit ({pb.data.n_samples} samples{where}): trust region {info['status']} after "
                f"{info['evaluations']} evaluations ({info['seconds']:.1f} s), normalised rms residual {rms_pre:.3g}"
                + routes_text(info))
        same = [a["start"] for a in run.attempts[:-1] if abs(rms_pre / a["rms_normalised"] - 1.0) < SAME_PREFIT]
        if same:
            attempt["fit_skipped"] = f"pre-fit ended where start {same[0]}'s did"
            run.say(f"start {k + 1}: the pre-fit ended where start {same[0]}'s did ({rms_pre:.3g}), the same basin: "
                    "not fitted again")
            return None
        if run.recording.has_pressures and ABOVE_NOISE_WARNING < rms_pre <= MODEL_SHORT:
            short = run.problem(run.window_stop, SHORT_SEGMENTS, start=run.window_start)
            v_pre, rms_pre, route = self.stages.short_segments(short, pb, lo, hi, theta0, v_pre, rms_pre,
                                                               run.window_recording)
            attempt["short_segments"] = route
            run.say(f"short segments ({SHORT_SEGMENTS} samples): pre-fit {route['rms_short_normalised']:.3g}, then "
                    f"{route['rms_normalised']:.3g} on the pre-fit's segments against {attempt['rms_normalised']:.3g}: "
                    f"{'kept' if route['kept'] else 'not kept'} ({route['seconds']:.1f} s)")
        run.prefit_points.append((rms_pre, k, pb.split(v_pre)[0]))
        return v_pre, rms_pre

    def _whole_fit(self, run: "FitRun", k: int, v_pre, rms_pre: float) -> float:
        """The whole estimation part from start ``k``'s pre-fit ``v_pre``: the trust region, then the exact
        problem (Gauss-Newton settling, else IPOPT); the fit joins ``run.fits``.  Returns its normalised rms."""
        pb, lo, hi = run.pb, run.lo, run.hi
        theta0, prefit_states = run.window[0].split(v_pre)
        x_init = self._whole_starts(run, theta0, prefit_states)
        v_ls, rms_ls, info = self.stages.whole_fit(pb, pb.join(theta0, x_init), lo, hi, rms_pre, finish=run.finish)
        run.say(f"start {k + 1}, fit ({run.setup.n_est} samples): trust region {info['status']} after "
                f"{info['evaluations']} evaluations ({info['seconds']:.1f} s), normalised rms residual {rms_ls:.3g}"
                + routes_text(info))
        # IPOPT on the kept route's point, unless the direct route's was already finished and kept; where
        # the continuation was kept over a finished direct route, the better of the two finished fits
        finished = info.pop("finished", None)
        if finished is not None and info["route"] == "direct":
            res, rms = finished
        else:
            res, rms = run.finish(v_ls, rms_ls)
        if finished is not None and info["route"] != "direct" and finished[0].objective < res.objective:
            res, rms = finished
        run.attempts[-1].update(fit_rms_normalised=rms, fit_routes=info["routes"], ipopt_status=res.status,
                                ipopt_iterations=res.iterations)
        run.fits.append((res.objective if np.isfinite(res.objective) else np.inf, k, res))
        run.say(f"start {k + 1}, fit: {stopped_by(res)}, normalised rms residual {rms:.3g}")
        return rms

    @staticmethod
    def _whole_starts(run: "FitRun", theta0, prefit_states) -> np.ndarray:
        """The whole part's segment start states at the pre-fit's parameters ``theta0``: chained from the
        recording's start, the pre-fit's own states where its window is the part's start, and the better of
        two first states (``docs/decisions/0014``).

        A window moved to where the piston moves begins at rest, with chamber pressures the window barely
        says anything about: there the chained states are kept throughout."""
        pb, window = run.pb, run.window[0]
        x_init = initial_starts(pb, theta0, run.recording, run.setup.n_est)
        fresh_first = x_init[0].copy()
        for j, first in enumerate(pb.starts.tolist() if run.window_start == 0 else []):
            if first in window.starts and first < window.starts[-1]:
                x_init[j] = prefit_states[list(window.starts).index(first)]
        x_init[0] = better_first_state(pb, theta0, [x_init[0], fresh_first])
        return x_init

    @staticmethod
    def _restart(run: "FitRun", k: int, rms: float, rms_pre: float) -> bool:
        """Whether start ``k``'s fit (``rms``, its pre-fit ``rms_pre``) calls for the next start: it ended well
        above its pre-fit (the window had a second basin), or both ended above noise (the window's basin need
        not be the whole part's); not where the pre-fit itself ends more than :data:`.rules.MODEL_SHORT` times
        above noise: the model lacks physics there, which no other start supplies (``docs/decisions/0009``)."""
        if not (well_above(rms, rms_pre) or min(rms, rms_pre) > ABOVE_NOISE_WARNING):
            return False
        if rms_pre > MODEL_SHORT:
            run.say(f"start {k + 1}: not restarting, the pre-fit itself ends {rms_pre:.3g} times above noise "
                    f"(more than {MODEL_SHORT:g}): the model lacks physics here")
            return False
        return True

    # ------------------------------------------------------------------------------------- the warm refit
    def _refit_warm(self, run: "FitRun", warm_start: FitResult):
        """A refit from ``warm_start``'s parameters and states: no pre-fit, no other starts; the trust region
        with a looser tolerance (near the optimum it only has to bring the new effect in), then IPOPT, one
        more IPOPT round where the iteration cap stopped it while the new effect was still coming in
        (``docs/decisions/0016``)."""
        pb, lo, hi, setup = run.pb, run.lo, run.hi, run.setup
        x_init = warm_states(warm_start, pb, setup.p_start, run.recording)
        v_ls, rms_ls, info = self.stages.warm_trust_region(pb, pb.join(setup.theta_start, x_init), lo, hi,
                                                           defect_weight=PENALTY_WEIGHT, tolerance=WARM_TOLERANCE)
        run.say(f"warm start: trust region {info['status']} after {info['evaluations']} evaluations "
                f"({info['seconds']:.1f} s), normalised rms residual {rms_ls:.3g}")
        res = self.stages.finish(pb, v_ls, lo, hi, self.max_iter, self.rtol, penalty=PENALTY_WEIGHT)
        rms = normalised_rms(pb, res)
        run.say(f"warm start: IPOPT {res.status} after {res.iterations} iterations ({res.seconds:.1f} s), "
                f"normalised rms residual {rms:.3g}")
        if (res.status == "Maximum_Iterations_Exceeded" and rms > ABOVE_NOISE_WARNING
                and rms < WARM_CONTINUE_BELOW * rms_ls):
            # stopped by the iteration cap while the new effect is still coming in: one more round, kept when
            # it lowers the residual; not where IPOPT has stalled (a wrong candidate creeping along)
            more = self.stages.finish(pb, res.v, lo, hi, self.max_iter, self.rtol, penalty=PENALTY_WEIGHT)
            if np.isfinite(more.objective) and more.objective < res.objective:
                more.iterations += res.iterations
                more.seconds += res.seconds
                res = more
                rms = normalised_rms(pb, res)
            run.say(f"warm start: IPOPT continued to {res.iterations} iterations, normalised rms residual {rms:.3g}")
        run.attempts.append({"start": "warm", "fit_rms_normalised": rms, "ipopt_status": res.status,
                             "ipopt_iterations": res.iterations, **info})
        run.fits.append((res.objective if np.isfinite(res.objective) else np.inf, 0, res))
        return _best(run)

    # ------------------------------------------------------------------------------------ the rescue routes
    def _rescue(self, run: "FitRun", res):
        """The rescue routes after the best fit ``res``: tracked starts where it ended above noise but neither
        it nor every pre-fit more than :data:`.rules.MODEL_SHORT` times above it (a recording too chaotic for
        chained starts), then the prediction-error route where it still ends above noise, however far (a
        recording too chaotic for the shooting problem's landscape; the filter itself tells that apart from
        a model that lacks physics).  Each kept when lower (``docs/decisions/0017``, ``0018``).  None without
        ``rescue``."""
        pb = run.pb
        rms_best = normalised_rms(pb, res)
        if self.rescue:
            if (ABOVE_NOISE_WARNING < rms_best <= MODEL_SHORT
                    and min(a["rms_normalised"] for a in run.attempts) <= MODEL_SHORT):
                res = self._tracked(run, res, rms_best)
            if normalised_rms(pb, res) > ABOVE_NOISE_WARNING and run.predicted is None:
                res = self._prediction_error(run, res)
        run.window[0].close()
        return res

    def _tracked(self, run: "FitRun", res, rms_best: float):
        """The tracked-starts route against the best fit ``res`` (normalised rms ``rms_best``): from its point, then
        from the other points the starts reached within :data:`.rules.MODEL_SHORT` (each start's pre-fit and
        fit; their parameters, the filter tracking the states from the best fit's first state), lowest first,
        :data:`.rules.TRACKED_STARTS` points at most, until one reaches noise; each kept when lower
        (``docs/decisions/0105``).  Its report goes to ``run.tracked``.  Returns the better fit."""
        pb, lo, hi = run.pb, run.lo, run.hi
        theta_best, starts = pb.split(res.v)
        others = run.prefit_points + [(normalised_rms(pb, fit), k, pb.split(fit.v)[0])
                                      for _, k, fit in run.fits if fit is not res]
        others = sorted((o for o in others if o[0] <= MODEL_SHORT and not np.array_equal(o[2], theta_best)),
                        key=lambda o: (o[0], o[1]))
        points = [(rms_best, res.v)] + [(rms, pb.join(theta, starts)) for rms, _, theta in others]
        tries, seconds = [], 0.0
        for rms_from, v in points[:TRACKED_STARTS]:
            res, info = better(res, *self.stages.tracked(pb, v, lo, hi, rms_best, run.finish))
            seconds += info["seconds"]
            tries.append({"from_rms_normalised": rms_from, **info})
            run.say("tracked starts" + ("" if len(tries) == 1 else f" from a point at {rms_from:.3g}") + ": "
                    + rounds_text(info) + f" against {rms_best:.3g}: {'kept' if info['kept'] else 'not kept'} "
                    f"({info['seconds']:.1f} s)")
            if info["kept"] and normalised_rms(pb, res) <= ABOVE_NOISE_WARNING:
                break
        kept = [t for t in tries if t["kept"]]
        run.tracked = {**(kept[-1] if kept else tries[-1]), "kept": bool(kept), "seconds": seconds, "tries": tries}
        return res

    def _prediction_error(self, run: "FitRun", res):
        """The prediction-error route from the start against the best fit ``res``, on a window at the recording's
        start (the filter tracks the whole part from there); its fit joins ``run.fits`` where kept, its report
        ``run.predicted``.  Returns the better of the two."""
        setup = run.setup
        if run.window_start > 0:
            window = run.problem(min(setup.n_est, self.prefit_samples))[0]
            first = initial_starts(window, setup.theta_start, run.recording, window.data.n_samples)[0]
        else:
            window, first = run.window[0], run.first_at_start
        try:
            res, route = better(res, *self.stages.prediction_error(
                window, run.pb, run.lo, run.hi, setup.theta_start, first, normalised_rms(run.pb, res), run.finish))
        finally:
            if window is not run.window[0]:
                window.close()
        run.predicted = route
        if route["kept"]:
            run.fits.append((res.objective, len(START_FACTORS), res))
        innovations = ", ".join(f"{a['rms_innovations']:.3g} (start {a['start'] + 1}"
                                + ("" if a["stages"] > 1 else ", broadest stage only") + f", {a['seconds']:.1f} s)"
                                for a in route["attempts"])
        run.say(f"prediction-error route: filter innovations {innovations}"
                + (", tracked starts " + rounds_text(route) if "rounds" in route else "")
                + f": {'kept' if route['kept'] else 'not kept'} ({route['seconds']:.1f} s)")
        return res

    # ---------------------------------------------------------------- uncertainty, validation and result
    def _uncertainty(self, run: "FitRun", res):
        """``(estimate, uncertainty)`` at the fit ``res``: the parameter vector (SI) and the covariance's dict
        (:func:`.uncertainty.covariance`); the continuity defects left open go to ``run.defect_sum_squares``."""
        pb = run.pb
        if not np.isfinite(res.objective):
            raise FitError(f"{_name(run.recording)}: the model could not be integrated at the optimiser's last point "
                           f"(IPOPT: {res.status}); check the rig file and the effects")
        theta, _ = pb.split(res.v)
        estimate = pb.params_of(theta)
        uncertainty = self.stages.uncertainty(pb, res.v)
        # the continuity defects left open at the optimum (state-scaled): a fit that ended in the penalty form
        # bought part of its residual with them, which a comparison of residuals alone would reward
        defects = pb.evaluate(res.v, derivatives=False)["g"]
        run.defect_sum_squares = float(np.dot(defects, defects)) if np.all(np.isfinite(defects)) else float("inf")
        pb.close()
        run.say("uncertainty: Gauss-Newton covariance done")
        return estimate, uncertainty

    def _validation(self, run: "FitRun", estimate, uncertainty: dict) -> dict:
        """The fitted model over the validation part, from the state the fit estimated at its start."""
        setup = run.setup
        x_boundary = uncertainty["states"][setup.n_est - 1].copy()
        return self.stages.validate(setup.model, estimate, run.recording, setup.n_est, x_boundary, setup.delay_s,
                                    setup.rig.stroke_m, self.rtol)

    @staticmethod
    def _build_result(run: "FitRun", res, estimate, uncertainty: dict, validation: dict) -> FitResult:
        """The :class:`FitResult`: estimates, standard errors, correlations, validation, the solver's path."""
        setup = run.setup
        result = FitResult.build(
            recording=run.recording, rig=setup.rig, model=setup.model, free=setup.free,
            parameters=_estimates(setup, estimate, uncertainty),
            correlation=uncertainty["correlation"][:len(setup.free), :len(setup.free)], params_vector=estimate,
            n_estimation=setup.n_est, sigma=uncertainty["sigma"], noise_std=setup.sigma, validation=validation,
            solver=run.solver_info(res), estimation_states=uncertainty["states"])
        run.say(f"done in {result.solver['seconds']:.1f} s: validation fit {result.fit_percent:.2f} %, normalised "
                f"residual {result.normalised_residual:.3g} (noise level 1)"
                + ("" if result.converged_to_noise else " -- ABOVE NOISE, see the warnings"))
        return result


def _best(run: FitRun):
    """The lowest fit of ``run.fits`` (the earlier start on a tie)."""
    return min(run.fits, key=lambda f: (f[0], f[1]))[2]


def _estimates(setup: FitSetup, estimate: np.ndarray, uncertainty: dict) -> dict:
    """``{name: ParameterEstimate}`` of the free parameters from the fitted parameter vector ``estimate`` (SI)."""
    parameters = {}
    for k, name in enumerate(setup.free):
        lo_b, hi_b = setup.bounds[k]
        i = setup.index[k]
        # IPOPT may end a hair outside a bound (its bound_relax_factor): report the bound itself, so a physical
        # range check never refuses a fitted value such as a static friction of -4e-7 N
        parameters[name] = ParameterEstimate(
            name=name, estimate=float(np.clip(estimate[i], lo_b, hi_b)),
            std=float(uncertainty["std"][k] * setup.scales[k]), start=float(setup.p_start[i]), lower=float(lo_b),
            upper=float(hi_b))
    return parameters
