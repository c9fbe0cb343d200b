"""ARX estimation by linear least squares (QR factorisation).

Model ``A(q) y(t) = B(q) u(t) + e(t)`` with ``A = 1 + a_1 q^-1 + ... + a_na q^-na``
and ``B = b_nk q^-nk + ... + b_{nk+nb-1} q^-(nk+nb-1)``.  The regression uses
the samples ``t = n, ..., N-1`` with ``n = max(na, nk+nb-1)`` so that every
regressor is measured (no assumption about data before the record).
"""
from __future__ import annotations

import numpy as np

from ._blas import one_blas_thread
from ._checks import check_data, check_enough_data, check_order, check_orders, scaled, unscale_poly
from ._diagnose import finish
from .data import IDData
from .errors import SysidError
from .linalg import qr_lstsq
from .polynomial import IDPoly

__all__ = ["ARX", "arx", "arx_regressors"]


def arx_regressors(y: np.ndarray, u: np.ndarray, na: int, nb: int, nk: int):
    """Regression matrix of an ARX model.

    Returns
    -------
    Phi : ndarray, shape (N - n, na + nb)
        Rows ``[-y(t-1) .. -y(t-na), u(t-nk) .. u(t-nk-nb+1)]``.
    target : ndarray, shape (N - n,)
        ``y(t)`` for ``t = n .. N-1``.
    n : int
        First regressed sample, ``max(na, nk + nb - 1)``.
    """
    N = y.size
    n = max(na, nk + nb - 1, 0)
    Phi = np.empty((N - n, na + nb))
    for i in range(na):
        Phi[:, i] = -y[n - 1 - i:N - 1 - i]
    for j in range(nb):
        d = nk + j
        Phi[:, na + j] = u[n - d:N - d]
    return Phi, y[n:], n


class ARX:
    """ARX estimator; ``ARX(na, nb, nk).fit(data)`` returns an :class:`IDPoly`.

    Parameters
    ----------
    na : int
        Number of poles (``>= 0``).
    nb : int
        Number of ``B`` coefficients (``>= 0``).
    nk : int
        Input delay in samples (``>= 0``).
    """

    def __init__(self, na: int, nb: int, nk: int = 1):
        self.na = na
        self.nb = nb
        self.nk = nk

    def fit(self, data: IDData) -> IDPoly:
        """Estimate the model from ``data``; sets ``model_`` and returns it.

        Raises :class:`SysidError` when the data cannot determine the parameters
        (rank-deficient regressors).
        """
        return self._fit(data, strict=True)

    @one_blas_thread
    def _fit(self, data: IDData, strict: bool) -> IDPoly:
        data = check_data(data)
        na = check_order(self.na, "na")
        nb = check_order(self.nb, "nb")
        nk = check_order(self.nk, "nk")
        if na + nb == 0:
            raise SysidError("na + nb must be at least 1, got na = nb = 0.")
        n = max(na, nk + nb - 1, 0)
        check_enough_data(data.N - n, na + nb, f"ARX[{na} {nb} {nk}]")
        original = data
        data, sy, su = scaled(data)
        Phi, target, n = arx_regressors(data.y, data.u, na, nb, nk)
        theta, rss, R11 = qr_lstsq(Phi, target, what=f"ARX[{na} {nb} {nk}]" if strict else None)
        neff, d = target.size, na + nb
        lam = rss / max(neff - d, 1)
        try:
            Rinv = np.linalg.inv(R11)
            cov = lam * (Rinv @ Rinv.T)
        except np.linalg.LinAlgError:  # only without strict: singular regressors
            cov = np.full((d, d), np.inf)
        B = np.zeros(nk + nb)
        B[nk:] = theta[na:]
        model = IDPoly(np.r_[1.0, theta[:na]], B, Ts=data.Ts, nk=nk, nb=nb,
                       noise_variance=lam, covariance=cov, structure="arx",
                       loss=rss / neff, n_samples=neff)
        unscale_poly(model, sy, su)
        if strict:
            finish(model, original, f"ARX[{na} {nb} {nk}] model")
        self.model_ = model
        return model


def arx(data: IDData, orders) -> IDPoly:
    """Estimate an ARX model, MATLAB style: ``arx(data, [na, nb, nk])``.

    Parameters
    ----------
    data : IDData
    orders : sequence of 3 int
        ``[na, nb, nk]``.

    Returns
    -------
    IDPoly
        With ``A``, ``B`` (``nk`` leading zeros), ``noise_variance`` (unbiased
        residual variance) and parameter ``covariance``.
    """
    na, nb, nk = check_orders(orders, ("na", "nb", "nk"), (0, 0, 0))
    return ARX(na, nb, nk).fit(data)
