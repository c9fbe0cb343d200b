"""The fit's first stage alone (:func:`prefit_recording`): how far a model gets on a short window
from the data sheet, without the whole fit."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import FitError
from ..model import Effect
from ..recording import Recording
from ..rig import Rig
from .rules import (DEFAULT_VALIDATION_FRACTION, MIN_ESTIMATION_SAMPLES, PREFIT_DEFECT_WEIGHTS, PREFIT_SAMPLES,
                    SEGMENT_SAMPLES, TRUST_REGION_EVALUATIONS)
from .setup import FitSetup, _name
from .initial import initial_starts
from .stages import prefit
from .threads import one_blas_thread

__all__ = ["prefit_recording", "PrefitResult"]


@dataclass
class PrefitResult:
    """The pre-fit alone (:func:`prefit_recording`): how far a model gets on a short window.

    Attributes
    ----------
    cost : float
        Residual sum of squares on the window in sensor-noise units (continuity defects not included).
    n_residuals : int
    normalised_residual : float
        ``sqrt(cost / n_residuals)`` (1 is the noise level).
    defect_cost : float
        The continuity defects the pre-fit left open, squared and weighted as its objective weighs them
        (the last of :data:`~.rules.PREFIT_DEFECT_WEIGHTS`): ``cost + defect_cost`` is what it minimised.
    estimates : dict
        ``{parameter name: value}`` of the free parameters at the end (SI units).
    samples : int
        Length of the window, samples.
    seconds : float
    """

    cost: float
    n_residuals: int
    normalised_residual: float
    estimates: dict
    samples: int
    seconds: float
    defect_cost: float = 0.0

    @property
    def objective(self) -> float:
        """What the pre-fit minimised at its end: the residual sum of squares plus the weighted defects.

        Why it, not the residual alone, compares models: without recorded pressures each segment's pressures
        (and an effect's own states) start free, and a pre-fit that ended with its segments apart bought part
        of its residual with the jumps; an effect with states of its own has more of them to buy with."""
        return self.cost + self.defect_cost

    @property
    def normalised_objective(self) -> float:
        """``sqrt(objective / n_residuals)``: the objective's rms in noise units (1 is the noise level)."""
        return float(np.sqrt(self.objective / max(self.n_residuals, 1)))


@one_blas_thread
def prefit_recording(recording: Recording, rig: Rig | str | None = None, effects: Sequence[Effect] = (),
                     free: Sequence[str] | None = None, *, samples: int = PREFIT_SAMPLES,
                     start_values: dict | None = None, validation_fraction: float | None = None,
                     segment_samples: int = SEGMENT_SAMPLES, rtol: float = 1e-6, threads: int = 2,
                     second_route: bool | None = None, max_evaluations: int = TRUST_REGION_EVALUATIONS,
                     start: int = 0) -> PrefitResult:
    """The first stage of :func:`fit_recording` alone: the pre-fit from the rig's values (or
    ``start_values``) on the first ``samples`` samples of the estimation part, with ``effects`` on.

    A cheap way to ask how well a model *can* explain the start of a recording from the data sheet,
    without the whole fit: diagnosis ranks candidate effects this way where the nominal fit ends far
    above noise (:mod:`pneusim.diagnosis.from_data_sheet`).  ``second_route`` and ``max_evaluations`` as in
    :func:`.stages.prefit`.  ``start``: the window begins at this sample of the estimation part instead
    of its first (the recording's estimation/validation split stays where ``validation_fraction`` puts
    it).  Raises :class:`FitError` like :func:`fit_recording`.
    """
    started = time.perf_counter()
    if start > 0:
        n = recording.n_samples
        split = int(round(n * (1.0 - (DEFAULT_VALIDATION_FRACTION if validation_fraction is None
                                      else validation_fraction))))
        if not 0 < start < split - MIN_ESTIMATION_SAMPLES:
            raise FitError(f"{_name(recording)}: a pre-fit window from sample {start} leaves fewer than "
                           f"{MIN_ESTIMATION_SAMPLES} samples "
                           f"before the validation part (from sample {split})")
        recording = recording.slice(recording.time_s[start], None)
        validation_fraction = (n - split) / (n - start)
    setup = FitSetup(recording, rig, effects, free, validation_fraction, None, start_values, segment_samples)
    pb, lo, hi = setup.problem(min(setup.n_est, int(samples)), rtol, threads)
    try:
        v0 = pb.join(setup.theta_start, initial_starts(pb, setup.theta_start, recording, pb.data.n_samples))
        v, _, _ = prefit(pb, v0, lo, hi, second_route=second_route, max_evaluations=max_evaluations)
        e = pb.evaluate(v, derivatives=False)
        if not e["ok"]:
            raise FitError(f"{_name(recording)}: the model could not be integrated at the pre-fit's end")
        theta, _ = pb.split(v)
        p = pb.params_of(theta)
    finally:
        pb.close()
    cost = float(np.dot(e["r"], e["r"]))
    n_res = int(e["r"].size)
    defects = PREFIT_DEFECT_WEIGHTS[-1] ** 2 * float(np.dot(e["g"], e["g"]))
    return PrefitResult(cost, n_res, float(np.sqrt(cost / max(n_res, 1))),
                        {name: float(p[i]) for name, i in zip(setup.free, setup.index)}, int(pb.data.n_samples),
                        time.perf_counter() - started, defects)
