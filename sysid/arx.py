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


def _qr_lstsq(Phi: np.ndarray, target: np.ndarray, what: str | None = None):
    """Least squares by QR of ``[Phi, target]``.

    Parameters
    ----------
    Phi : ndarray, shape (n, d)
    target : ndarray, shape (n,)
    what : str or None
        Name of the model for the error message.  When given, a rank-deficient
        ``Phi`` raises :class:`SysidError`; otherwise the minimum-norm solution
        is returned (internal start-value computations).

    Returns
    -------
    theta : ndarray, shape (d,)
    rss : float
        Residual sum of squares.
    R11 : ndarray, shape (d, d)
        Upper-triangular factor of ``Phi``.

    Notes
    -----
    Only numpy's LAPACK is used: alternating between numpy's and scipy's
    OpenBLAS builds makes the idle thread pool of one spin against the other
    (milliseconds per switch on a busy machine).
    """
    d = Phi.shape[1]
    R = np.linalg.qr(np.column_stack([Phi, target]), mode="r")
    R11 = R[:d, :d]
    rss = float(R[d, d] ** 2) if R.shape[0] > d else 0.0
    # column i is (numerically) a combination of columns 0..i-1 when |R_ii| << |Phi_i|
    colnorm = np.sqrt(np.einsum("ij,ij->j", Phi, Phi))
    tol = max(Phi.shape) * np.finfo(float).eps
    bad = np.flatnonzero(np.abs(np.diag(R11)) <= tol * np.maximum(colnorm, np.finfo(float).tiny))
    if bad.size:
        if what is not None:
            raise SysidError(
                f"the data cannot support {what}: regressor {int(bad[0]) + 1} of {d} is a linear combination "
                f"of the others (input not persistently exciting, or orders too high for noise-free data).")
        theta = np.linalg.lstsq(R11, R[:d, d], rcond=None)[0]
        return theta, rss, R11
    theta = np.linalg.solve(R11, R[:d, d])
    return theta, rss, R11


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
        theta, rss, R11 = _qr_lstsq(Phi, target, what=f"ARX[{na} {nb} {nk}]" if strict else None)
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
