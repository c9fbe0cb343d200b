"""Physical parameter estimation: the one CasADi model fitted to a recording by IPOPT.

``fit_recording(recording, rig, effects)`` returns a :class:`FitResult` with
estimates, standard errors, correlations, identifiability warnings and a
validation fit on data the optimiser never saw.
"""

from .fitter import fit_recording
from .setup import noise_std_estimate
from .prefit import PrefitResult, prefit_recording
from .parameters import DEFAULT_FREE, EFFECT_FREE
from .result import FitResult, ParameterEstimate

__all__ = ["fit_recording", "prefit_recording", "PrefitResult", "noise_std_estimate", "FitResult", "ParameterEstimate", "DEFAULT_FREE", "EFFECT_FREE"]
