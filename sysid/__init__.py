"""sysid: black-box system identification with MATLAB conventions.

MATLAB-style functions (``iddata``, ``arx``, ``armax``, ``oe``, ``bj``,
``n4sid``, ``ssest``, ``tfest``, ``rls``, ``predict``, ``compare``, ``resid``) are thin
wrappers around estimator objects (``ARX(na, nb, nk).fit(data)``).
Independent of :mod:`pneusim`.
"""
from .errors import SysidError, SysidWarning
from .data import IDData, iddata, detrend
from .recording import load_recording
from .polynomial import IDPoly, idpoly
from .arx import ARX, arx
from .pem import PEM, ARMAX, OE, BJ, armax, oe, bj, pem
from .recursive import RecursiveARX, RecursiveARMAX, RLSResult, rls, check_rls_options
from .statespace import IDSS
from .subspace import N4SID, n4sid
from .ssest import SSEst, ssest
from .tfest import IDTF, TFEst, tfest
from .predict import predict, simulate, compare, fit_percent
from .analysis import ResidResult, resid, aic, fpe, bic, struc, arxstruc, selstruc, delayest
from .convert import to_scipy, to_control, from_scipy, from_control

__all__ = [
    "SysidError", "SysidWarning",
    "IDData", "iddata", "detrend", "load_recording",
    "IDPoly", "idpoly",
    "ARX", "arx",
    "PEM", "ARMAX", "OE", "BJ", "armax", "oe", "bj", "pem",
    "RecursiveARX", "RecursiveARMAX", "RLSResult", "rls", "check_rls_options",
    "IDSS", "N4SID", "n4sid", "SSEst", "ssest",
    "IDTF", "TFEst", "tfest",
    "predict", "simulate", "compare", "fit_percent",
    "ResidResult", "resid", "aic", "fpe", "bic", "struc", "arxstruc", "selstruc", "delayest",
    "to_scipy", "to_control", "from_scipy", "from_control",
]
