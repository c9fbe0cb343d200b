"""Least squares shared by the estimators (internal to :mod:`sysid`, public to its modules)."""
from __future__ import annotations

import numpy as np

from .errors import SysidError

__all__ = ["qr_lstsq"]


def qr_lstsq(Phi: np.ndarray, target: np.ndarray, what: str | None = None):
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
