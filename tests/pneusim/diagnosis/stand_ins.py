"""Stand-ins for whole fits, and a diagnosis run to pass them in as stages, for the diagnosis's rule tests.

A whole fit costs seconds to minutes; a :class:`StandInFit` has a set outcome instead: its estimation residual
rms in noise units (the noise std is 1, so :func:`pneusim.diagnosis.refits.estimation_cost` gives ``rms**2 n``),
its validation fit % and its effects.  :func:`stand_in_run` builds the :class:`~pneusim.diagnosis.run.DiagnosisRun`
a step reads, with the stand-in fits, screenings and keep test passed as its stages.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from pneusim.diagnosis import DiagnosisStages
from pneusim.diagnosis.run import DiagnosisRun, NominalBaseline

#: the sensor noise of every stand-in: the residuals' rms is in its units
NOISE = {"position_m": 1.0}


class StandInFit:
    """A fit with a set outcome: estimation residual rms ``rms`` (noise units) on ``n`` residuals, validation fit
    ``fit_percent`` %, ``effects`` switched on; no fitted effect parameter."""

    def __init__(self, rms: float, fit_percent: float, effects=(), n: int = 1000):
        self.rms, self.fit_percent, self.effects_ = rms, fit_percent, list(effects)
        self.recording = SimpleNamespace(position_m=np.zeros(n))
        self.n_estimation = n
        self.sigma = {"position_m": rms}
        self.solver, self.parameters, self.estimates = {}, {}, {}


def cost_fit(cost: float, effects=()) -> StandInFit:
    """A stand-in fit whose estimation cost is ``cost`` on one residual."""
    return StandInFit(math.sqrt(cost), math.nan, effects, n=1)


def stand_in_run(baseline: NominalBaseline, recording=None, *, trials=None, refits=None, second_only=None,
                 **stages) -> DiagnosisRun:
    """A run on ``baseline`` whose stages are today's but those given (``refit=``, ``fit=``, ``screen=``,
    ``keep_test=``, ...); ``trials``, ``refits`` and ``second_only`` are the dicts given (the test reads them)."""
    run = DiagnosisRun(recording, None, baseline, DiagnosisStages(**stages), n_screen=baseline.n_residuals)
    run.trials = {} if trials is None else trials
    run.refits = {} if refits is None else refits
    run.second_only = {} if second_only is None else second_only
    return run
