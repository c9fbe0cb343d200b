"""One fit's state while :class:`.estimator.PhysicalFit` runs (:class:`FitRun`), and how its fits are finished
and compared: the exact constrained problem from a trust region's point (:meth:`FitRun.finish`), the
normalised residual of a finished fit, how its optimiser stopped, and the better of two fits."""

from __future__ import annotations

import time

import numpy as np

from ..recording import Recording
from .rules import ABOVE_NOISE_WARNING, ACCEPTABLE_DEFECT_FACTOR, DEFECT_TOL_PER_RTOL, PENALTY_WEIGHT
from .setup import FitSetup
from .shooting import ShootingProblem
from .stage_lines import StageLines

__all__ = ["FitRun", "normalised_rms", "stopped_by", "better"]


class FitRun:
    """One fit's state: the setup, the whole estimation part's problem, the pre-fit's window and its problem,
    the attempts and fits so far, the rescue routes' reports, and the stage lines.  ``options`` is the
    :class:`.estimator.PhysicalFit` running it (its options and stages)."""

    def __init__(self, options, recording: Recording, warm_start, start_values):
        self.started, self.cpu_started = time.perf_counter(), time.process_time()
        self.say = StageLines(options.quiet and not options.verbose, self.started)
        self.options, self.recording, self.warm = options, recording, warm_start is not None
        validation_fraction = options.validation_fraction
        if validation_fraction is None and warm_start is not None:
            # the warm fit's split: round(n * (n_est / n)) gives back n_est exactly
            validation_fraction = 1.0 - warm_start.n_estimation / recording.n_samples
        self.setup = FitSetup(recording, options.rig, options.effects, options.free, validation_fraction,
                              warm_start, start_values, options.segment_samples)
        self.pb, self.lo, self.hi = self.problem(self.setup.n_est)
        self.window = None
        self.window_start = self.window_stop = 0
        self.window_recording = recording
        self.first_at_start = None
        self.attempts, self.fits = [], []
        self.prefit_points = []   # (normalised rms on the window, start, scaled parameters) of each pre-fit
        self.tracked = self.predicted = None
        self.defect_sum_squares = float("nan")

    def problem(self, stop: int, segment: int | None = None, start: int = 0):
        """``(problem, lower, upper)`` of samples ``start`` to ``stop - 1`` (:meth:`.setup.FitSetup.problem`)."""
        return self.setup.problem(stop, self.options.rtol, self.options.threads, segment, start)

    def open_window(self, samples: int) -> None:
        """The pre-fit's window of ``samples`` samples: the estimation part's first, unless the piston hardly
        moves there (:meth:`.setup.FitSetup.prefit_start`); its recording and its problem."""
        start = self.setup.prefit_start(samples)
        stop = start + min(self.setup.n_est, samples)
        rec = self.recording
        self.window_start, self.window_stop = start, stop
        self.window_recording = rec if start == 0 else rec.slice(rec.time_s[start], rec.time_s[stop])
        self.window = self.problem(stop, start=start)

    def finish(self, v, rms: float = float("inf")):
        """The exact constrained problem on the whole estimation part from ``v`` (its trust region's normalised
        rms ``rms``): ``(result, normalised rms)``.  Gauss-Newton settling where ``rms`` is at noise, else (or
        where that does not settle) IPOPT; where IPOPT ends at noise in its penalty form, the defects it left
        open are settled from there (:meth:`settle_open`)."""
        options = self.options
        if rms <= ABOVE_NOISE_WARNING:
            done = options.stages.settle(self.pb, v, rms, options.rtol, self.lo, self.hi)
            if done is not None:
                return done, normalised_rms(self.pb, done)
        done = options.stages.finish(self.pb, v, self.lo, self.hi, options.max_iter, options.rtol,
                                     penalty=PENALTY_WEIGHT)
        return self.settle_open(done)

    def settle_open(self, res):
        """``(result, normalised rms)``: IPOPT's result ``res``, or where it ended at noise with continuity
        defects open beyond IPOPT's own acceptable level (its penalty form, or a constrained run stopped by its
        iteration cap), the Gauss-Newton settling of the constrained problem from its point when that settles
        (iterations and seconds counted on top).

        Why: whether IPOPT's constrained run ends within its iteration cap, and so whether the answer comes from
        its penalty form with the defects left open, depends on the last bits of its steps; the settled point
        is the same constrained optimum either way (``docs/decisions/0100``)."""
        rms, options = normalised_rms(self.pb, res), self.options
        if not (rms <= ABOVE_NOISE_WARNING and res.max_defect > ACCEPTABLE_DEFECT_FACTOR * DEFECT_TOL_PER_RTOL
                * options.rtol):
            return res, rms
        settled = options.stages.settle(self.pb, res.v, rms, options.rtol, self.lo, self.hi)
        if settled is None:
            return res, rms
        settled.iterations += res.iterations
        settled.seconds += res.seconds
        settled.formulation = f"{settled.formulation}; from IPOPT's {res.formulation}"
        return settled, normalised_rms(self.pb, settled)

    def solver_info(self, res) -> dict:
        """The result's ``solver`` dict: the final solver's status and counts, the path taken, the seconds."""
        return {"status": res.status, "stopped_by": stopped_by(res), "ipopt_success": res.success,
                "iterations": res.iterations,
                "seconds": time.perf_counter() - self.started, "cpu_seconds": time.process_time() - self.cpu_started,
                "ipopt_seconds": res.seconds,
                "max_defect": res.max_defect, "defect_sum_squares": self.defect_sum_squares,
                "prefit_attempts": self.attempts, "tracked_route": self.tracked,
                "prediction_error_route": self.predicted, "rescue": bool(self.options.rescue and not self.warm),
                "formulation": res.formulation, "warm_start": self.warm,
                "segments": int(self.pb.n_segments), "segment_samples": self.setup.seg}

    def close(self) -> None:
        """Release the problems' integrator threads (again: closing twice is harmless)."""
        self.pb.close()
        if self.window is not None:
            self.window[0].close()


def stopped_by(res) -> str:
    """How the last optimiser of a fit stopped, in words: Gauss-Newton settling or IPOPT, its status, iterations,
    seconds and formulation.  Only a description: the verdict is the residual's (:class:`.result.FitResult`)."""
    if res.status == "Gauss_Newton_Settled":
        rule = ("the residual no longer moving within the scatter of its steps" if "scatter" in res.formulation
                else "the next step within a tenth of every standard error")
        return (f"settled by Gauss-Newton steps on the constrained problem (largest defect {res.max_defect:.2g}, "
                f"{rule}; {res.formulation})")
    return f"IPOPT {res.status} after {res.iterations} iterations ({res.seconds:.1f} s; {res.formulation})"


def normalised_rms(pb: ShootingProblem, res) -> float:
    """The normalised rms residual of an IPOPT result (noise level 1)."""
    return float(np.sqrt(res.objective / max(pb.n_residuals, 1)))


def better(res, done, info: dict):
    """``(fit, info)``: a route's finished fit ``done`` where it is finite and lower than ``res`` (its
    iterations and seconds counted on top of ``res``'s), else ``res``; ``info["kept"]`` says which."""
    info["kept"] = bool(done is not None and np.isfinite(done.objective) and done.objective < res.objective)
    if not info["kept"]:
        return res, info
    done.iterations += res.iterations
    done.seconds += res.seconds
    return done, info

