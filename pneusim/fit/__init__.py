"""Physical parameter estimation: the one CasADi model fitted to a recording by IPOPT.

``fit_recording(recording, rig, effects)`` returns a :class:`FitResult` with
estimates, standard errors, correlations, identifiability warnings and a
validation fit on data the optimiser never saw.  It runs :class:`PhysicalFit`,
an estimator whose stages (:class:`FitStages`) can be swapped one by one; the
thresholds that pick a fit's path and verdict are in :mod:`.rules`.
"""

from .fitter import fit_recording
from .estimator import FitStages, PhysicalFit
from .setup import noise_std_estimate
from .prefit import PrefitResult, prefit_recording
from .parameters import DEFAULT_FREE, EFFECT_FREE
from .result import FitResult, ParameterEstimate

__all__ = ["fit_recording", "PhysicalFit", "FitStages", "prefit_recording", "PrefitResult", "noise_std_estimate",
           "FitResult", "ParameterEstimate", "DEFAULT_FREE", "EFFECT_FREE"]
