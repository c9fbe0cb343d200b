"""State-space estimation by prediction-error minimisation (MATLAB ``ssest``).

Start: :func:`sysid.n4sid`.  Refinement: the innovations model of order
``nx`` is the ARMAX model ``A y = B u + C e`` with ``na = nc = nx`` and
``nb = nx`` (``nk = 1``; ``nb = nx + 1, nk = 0`` with feedthrough), whose
prediction error is minimised by Levenberg–Marquardt on the exact gradient
(:class:`sysid.PEM`).  The result is returned in observer-canonical form
(:func:`sysid.statespace.idss_from_armax`) with the covariance of the
ARMAX-equivalent coefficients.
"""
from __future__ import annotations

import warnings as _warnings

from ._blas import one_blas_thread
from ._checks import check_data
from ._diagnose import finish
from .data import IDData
from .errors import SysidWarning
from .pem import ARMAX
from .polynomial import is_stable_poly
from .statespace import IDSS, idss_from_armax
from .subspace import N4SID

__all__ = ["SSEst", "ssest"]


class SSEst:
    """Prediction-error state-space estimator: ``SSEst(nx).fit(data)`` returns an :class:`IDSS`.

    Parameters
    ----------
    nx : int or None
        State dimension; ``None`` lets :class:`N4SID` choose it from the singular values.
    feedthrough : bool
        Estimate ``D`` (default: ``D = 0``, as MATLAB).
    max_iter : int
        Maximum Levenberg–Marquardt iterations.
    tol : float
        Relative cost decrease below which the search stops.
    **n4sid_options
        ``horizon``, ``max_order``, ``method`` of the start estimate.
    """

    def __init__(self, nx=None, feedthrough=False, max_iter=50, tol=1e-9, **n4sid_options):
        self.nx = nx
        self.feedthrough = feedthrough
        self.max_iter = max_iter
        self.tol = tol
        self.n4sid_options = n4sid_options

    @one_blas_thread
    def fit(self, data: IDData) -> IDSS:
        """Estimate; sets ``model_`` (and the start ``start_``) and returns an :class:`IDSS`."""
        data = check_data(data)
        with _warnings.catch_warnings():  # the start and the ARMAX step are judged once, at the end
            _warnings.simplefilter("ignore", SysidWarning)
            model = self._fit(data)
        return finish(model, data, f"ssest model (nx = {model.nx})")

    def _fit(self, data):
        start = N4SID(self.nx, feedthrough=self.feedthrough, **self.n4sid_options).fit(data)
        p0 = start.to_idpoly()
        nx = start.nx
        nk = 0 if self.feedthrough else 1
        nb = nx + 1 if self.feedthrough else nx
        p0 = p0 if (p0.nk, p0.nb, p0.na, p0.nc) == (nk, nb, nx, nx) and is_stable_poly(p0.C) else None
        p = ARMAX(nx, nb, nx, nk, max_iter=self.max_iter, tol=self.tol, init_sys=p0).fit(data)
        model = idss_from_armax(p, noise_variance=p.noise_variance, covariance=p.covariance,
                                loss=p.loss, n_samples=p.n_samples,
                                singular_values=start.singular_values, report=dict(p.report))
        self.start_ = start
        self.model_ = model
        return model


def ssest(data: IDData, nx=None, **options) -> IDSS:
    """MATLAB ``ssest(data, nx)``: n4sid start refined by prediction-error minimisation.

    Parameters
    ----------
    data : IDData
    nx : int or None
        State dimension (``None``: chosen from the singular values).
    **options
        ``feedthrough``, ``max_iter``, ``tol`` and the :class:`N4SID` options.

    Returns
    -------
    IDSS
        Observer-canonical model with ``covariance`` of :attr:`IDSS.parameters`.
    """
    return SSEst(nx, **options).fit(data)
