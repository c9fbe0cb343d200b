"""Fit the physical model to a recording: :func:`fit_recording`, the one call everyone uses.

It runs :class:`.estimator.PhysicalFit` with these options (the method, stage by stage, is in
:mod:`.estimator`'s docstring; its thresholds in :mod:`.rules`).
"""

from __future__ import annotations

from typing import Sequence

from ..model import Effect
from ..recording import Recording
from ..rig import Rig
from .estimator import PhysicalFit
from .result import FitResult
from .rules import IPOPT_MAX_ITER, PREFIT_SAMPLES, PREFIT_STARTS, SEGMENT_SAMPLES

__all__ = ["fit_recording"]


def fit_recording(recording: Recording, rig: Rig | str | None = None, effects: Sequence[Effect] = (),
                  free: Sequence[str] | None = None, *, validation_fraction: float | None = None,
                  segment_samples: int = SEGMENT_SAMPLES, prefit_samples: int = PREFIT_SAMPLES,
                  starts: int = PREFIT_STARTS, rtol: float = 1e-6, threads: int = 2, max_iter: int = IPOPT_MAX_ITER,
                  verbose: bool = False, quiet: bool = False, warm_start: FitResult | None = None,
                  start_values: dict | None = None, rescue: bool = True) -> FitResult:
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
        IPOPT iterations per round on the exact problem (:func:`.constrained.solve_ipopt_exact`).
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

    rescue : bool
        The rescue routes where the best fit still ends above noise (tracked starts, then the prediction-error
        route; :mod:`.rescue_routes`), on by default.  They find the optimum of a model that is right on a
        recording too chaotic for the shooting problem's landscape; where the model is known to lack physics
        (a diagnosis's candidate fitted from the data sheet), above noise is the answer and they are skipped:
        ``solver["rescue"]`` says which.

    Raises
    ------
    FitError
        The recording does not match the rig, does not excite the free
        parameters, or the optimiser could not fit it.
    """
    return PhysicalFit(rig, effects, free, validation_fraction=validation_fraction, segment_samples=segment_samples,
                       prefit_samples=prefit_samples, starts=starts, rtol=rtol, threads=threads, max_iter=max_iter,
                       verbose=verbose, quiet=quiet, rescue=rescue).fit(recording, warm_start=warm_start,
                                                                       start_values=start_values)
