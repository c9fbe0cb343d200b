"""sysid: black-box system identification with MATLAB conventions.

MATLAB-style functions (``iddata``, ``arx``, ``armax``, ``oe``, ``bj``,
``n4sid``, ``tfest``, ``rls``, ``predict``, ``compare``, ``resid``) are thin
wrappers around estimator objects (``ARX(na, nb, nk).fit(data)``).
Independent of :mod:`pneusim`.
"""
from .errors import SysidError
from .data import IDData, iddata, detrend, load_recording
from .polynomial import IDPoly, idpoly
from .arx import ARX, arx
from .pem import PEM, ARMAX, OE, BJ, armax, oe, bj, pem
from .recursive import RecursiveARX, RecursiveARMAX, RLSResult, rls
from .predict import predict, simulate, compare, fit_percent

__all__ = [
    "SysidError",
    "IDData", "iddata", "detrend", "load_recording",
    "IDPoly", "idpoly",
    "ARX", "arx",
    "PEM", "ARMAX", "OE", "BJ", "armax", "oe", "bj", "pem",
    "RecursiveARX", "RecursiveARMAX", "RLSResult", "rls",
    "predict", "simulate", "compare", "fit_percent",
]
