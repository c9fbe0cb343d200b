"""Subspace identification (N4SID-type) of an innovations state-space model.

Steps (Van Overschee & De Moor 1996, ch. 4; Verhaegen 1994 for the
weighting):

1. block Hankel matrices of past/future inputs and outputs, horizon ``i``;
2. oblique projection ``O_i = Y_f /_{U_f} W_p`` of future outputs on past
   data ``W_p = [U_p; Y_p]`` along future inputs, by least squares;
3. SVD of ``O_i`` weighted by the projection orthogonal to ``U_f``; the
   order is the largest gap of the log singular values when not given;
4. state sequence ``X = S^-1/2 U^T O_i``; ``A, C`` and the Kalman gain ``K``
   by least squares on consecutive states and the residual covariances;
5. ``B, D`` and the initial state re-estimated by least squares on the
   simulated output (so the model is good in simulation, MATLAB ``compare``);
6. parameter covariance of the basis-independent ARMAX-equivalent
   coefficients (:attr:`IDSS.parameters`): ``sigma^2 (J^T J)^-1`` with ``J`` the
   exact prediction-error gradient at the estimate, as for the PEM models.
   A subspace estimate is not a minimiser of the prediction error and not
   efficient, so these bounds are somewhat optimistic for it (about 1.2x
   too small in simulation studies); :func:`sysid.ssest` refines the estimate
   by prediction-error minimisation, for which they hold.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from ._blas import one_blas_thread
from ._checks import check_data, check_order
from .data import IDData
from .errors import SysidError
from .statespace import IDSS

__all__ = ["N4SID", "n4sid"]


def _hankel(x: np.ndarray, start: int, rows: int, cols: int) -> np.ndarray:
    idx = start + np.arange(rows)[:, None] + np.arange(cols)[None, :]
    return x[idx]


class N4SID:
    """Subspace estimator; ``N4SID(nx).fit(data)`` returns an :class:`IDSS`.

    Parameters
    ----------
    nx : int or None
        State dimension; ``None`` picks it from the singular values (up to ``max_order``).
    horizon : int or None
        Past and future horizon ``i`` (default ``max(2 * nx_max, 10)`` capped by data length).
    feedthrough : bool
        Estimate ``D`` (MATLAB default: no, ``D = 0``).
    max_order : int
        Largest order considered when ``nx`` is None.
    method : {"shift", "states"}
        ``A, C`` from the shift invariance of the observability matrix
        (default, MOESP-like) or by regression on the estimated states.
    """

    def __init__(self, nx=None, horizon=None, feedthrough=False, max_order=10, method="shift"):
        self.method = method
        self.nx = nx
        self.horizon = horizon
        self.feedthrough = feedthrough
        self.max_order = max_order

    @one_blas_thread
    def fit(self, data: IDData) -> IDSS:
        """Estimate the model; sets ``model_`` and returns it."""
        data = check_data(data)
        y, u, N = data.y, data.u, data.N
        nmax = check_order(self.max_order, "max_order", 1)
        if self.nx is not None:
            nx = check_order(self.nx, "nx", 1)
            nmax = nx
        i = self.horizon if self.horizon is not None else max(2 * nmax, 10)
        i = check_order(i, "horizon", 1)
        j = N - 2 * i + 1
        if i <= nmax or j < 4 * i + 10:
            raise SysidError(f"orders are too high for the data: n4sid with nx = {nmax} needs horizon > nx and "
                             f"at least {2 * i + 4 * i + 9} samples, got horizon {i} and {N} samples.")
        Up, Uf = _hankel(u, 0, i, j), _hankel(u, i, i, j)
        Yp, Yf = _hankel(y, 0, i, j), _hankel(y, i, i, j)
        Wp = np.vstack([Up, Yp])
        # one QR (= LQ of [Uf; Wp; Yf]); then Yf = L31 Q1 + L32 Q2 + L33 Q3, Wp = L21 Q1 + L22 Q2
        L = np.linalg.qr(np.vstack([Uf, Wp, Yf]).T, mode="r").T
        L22 = L[i:3 * i, i:3 * i]
        L32 = L[3 * i:, i:3 * i]
        # oblique projection Oi = Yf /_Uf Wp = Lw Wp with Lw = L32 L22^+; weighted by the
        # projection orthogonal to Uf its column space is that of Lw L22 = L32
        Lw = L32 @ np.linalg.pinv(L22)
        Us, s, _ = np.linalg.svd(L32)
        s = s / np.sqrt(j)
        if self.nx is None:
            k = min(nmax, s.size - 1)
            gaps = np.log(s[:k] + 1e-300) - np.log(s[1:k + 1] + 1e-300)
            nx = int(np.argmax(gaps)) + 1
        U1 = Us[:, :nx]
        sq = np.sqrt(s[:nx])
        Gam = U1 * sq
        # states X(t), t = i .. i+j-1
        X = (U1.T / sq[:, None]) @ (Lw @ Wp)
        Xc, Xn = X[:, :-1], X[:, 1:]
        uc = u[i:i + j - 1]
        yc = y[i:i + j - 1]
        if self.method == "shift":
            # A and C from the shift invariance of the extended observability matrix
            A = np.linalg.lstsq(Gam[:-1], Gam[1:], rcond=None)[0]
            Cm = Gam[:1]
        elif self.method == "states":
            # A and C by least squares on consecutive states
            reg = np.vstack([Xc, uc])
            th = np.linalg.lstsq(reg.T, np.vstack([Xn, yc[None, :]]).T, rcond=None)[0].T
            A, Cm = th[:nx, :nx], th[nx:, :nx]
        else:
            raise SysidError(f"method must be 'shift' or 'states', got {self.method!r}.")
        # input terms of the state and output equations given A, C; residuals -> K
        Rx = Xn - A @ Xc
        Ry = yc - (Cm @ Xc).ravel()
        bs = np.linalg.lstsq(uc[:, None], Rx.T, rcond=None)[0].T
        w = Rx - bs @ uc[None, :]
        if self.feedthrough:
            ds = float(uc @ Ry) / float(uc @ uc)
            v = Ry - ds * uc
        else:
            v = Ry
        Svv = float(v @ v) / v.size
        K = (w @ v / v.size / Svv).reshape(nx, 1)
        if np.any(np.abs(np.linalg.eigvals(A - K @ Cm)) >= 1.0):
            K = np.zeros((nx, 1))  # keep the predictor stable; fall back to output error
        # B, D, x0 by least squares on the simulated output, given A and C
        B, D = self._input_matrices(A, Cm, y, u)
        model = IDSS(A, B, Cm, D, K, Ts=data.Ts, noise_variance=Svv, singular_values=s,
                     report=dict(horizon=i, gamma=Gam))
        model.covariance, model.loss = _pem_covariance(model, y, u)
        model.n_samples = N
        self.model_ = model
        return model

    def _input_matrices(self, A, C, y, u):
        n = A.shape[0]
        N = y.size
        # y_sim(t) = sum_k B_k * [C (qI-A)^-1 e_k u](t) + D u(t) + C A^t x0
        cols = []
        eye = np.eye(n)
        # transfer function C (zI-A)^-1 e_k in q^-1 form: num_k / det
        den = np.poly(A)
        for k in range(n):
            num = _ss_num(A, eye[:, [k]], C)
            cols.append(lfilter(num, den, u))
        free = np.empty((N, n))
        x = np.eye(n)
        # free response C A^t (cheap: n x n per step only for the first few hundred samples)
        for t in range(N):
            free[t] = C @ x
            x = A @ x
            if not np.any(np.abs(x) > 1e-14) and t > 10:
                free[t + 1:] = 0.0
                break
        Xr = np.column_stack(cols + ([u] if self.feedthrough else []) + [free])
        th, *_ = np.linalg.lstsq(Xr, y, rcond=None)
        B = th[:n].reshape(n, 1)
        D = np.array([[th[n] if self.feedthrough else 0.0]])
        return B, D


def _pem_covariance(model: IDSS, y, u):
    """``(sigma^2 (J^T J)^-1, V/N)`` of the ARMAX-equivalent parameters at ``model`` (None if undefined)."""
    from .pem import _jacobian, _residual
    p = model.to_idpoly()
    eps, v, w = _residual(p, y, u)
    V = float(eps @ eps)
    if not np.isfinite(V):  # unstable predictor: no prediction-error covariance
        return None, float("nan")
    J = _jacobian(p, y, u, eps, v, w)
    try:
        cov = V / max(y.size - p.n_parameters, 1) * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = None
    return cov, V / y.size


def _ss_num(A, B, C):
    from scipy.signal import ss2tf
    num, _ = ss2tf(A, B, C, np.zeros((1, 1)))
    return num.ravel()


def n4sid(data: IDData, nx=None, **options) -> IDSS:
    """MATLAB ``n4sid(data, nx)``; ``nx=None`` chooses the order from the singular values.

    Parameters
    ----------
    data : IDData
    nx : int or None
        State dimension.
    **options
        ``horizon``, ``feedthrough``, ``max_order`` (see :class:`N4SID`).

    Returns
    -------
    IDSS
    """
    return N4SID(nx, **options).fit(data)
