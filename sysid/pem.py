"""Prediction-error estimation of ARMAX, OE and BJ models.

Minimises ``V(theta) = sum eps(t)^2`` with the prediction error of
``A y = B/F u + C/D e``::

    eps = D/C (A y - B/F u)

by Levenberg–Marquardt on the exact gradient (Ljung 1999, sec. 10.3),
zero initial conditions.  Columns of ``d eps / d theta``:

* ``a_k``:  ``+ D/C y(t-k)``
* ``b_k``:  ``- D/(C F) u(t-k)``
* ``c_k``:  ``- 1/C eps(t-k)``
* ``d_k``:  ``+ 1/C w(t-k)`` with ``w = A y - B/F u``
* ``f_k``:  ``+ D/(C F) v(t-k)`` with ``v = B/F u``

Steps that would make ``C``, ``D`` or ``F`` unstable are rejected (the
damping is increased), so the predictor stays stable.  Start values:
Hannan–Rissanen (ARMAX), Steiglitz–McBride iterations (OE), OE followed by
Hannan–Rissanen on the output error (BJ).  Parameter covariance:
``sigma^2 (J^T J)^-1`` with ``sigma^2 = V / (N - d)``.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from ._blas import one_blas_thread
from ._checks import (check_data, check_enough_data, check_order, check_orders, check_tolerance, scaled,
                      unscale_poly)
from ._diagnose import finish
from .arx import arx_regressors
from .data import IDData
from .errors import SysidError
from .linalg import qr_lstsq
from .polynomial import IDPoly, is_stable_poly, reflect_roots

__all__ = ["PEM", "ARMAX", "OE", "BJ", "armax", "oe", "bj", "pem"]


def _shift(x: np.ndarray, k: int) -> np.ndarray:
    out = np.zeros_like(x)
    out[k:] = x[:x.size - k]
    return out


def prediction_errors(m: IDPoly, y, u):
    """Prediction errors of ``m`` on ``y, u`` from zero initial conditions, and the filtered signals.

    Returns
    -------
    eps : ndarray, shape (N,)
        ``D/C (A y - B/F u)``.
    v : ndarray, shape (N,)
        ``B/F u``.
    w : ndarray, shape (N,)
        ``A y - v``.
    """
    v = lfilter(m.B, m.F, u)
    w = lfilter(m.A, [1.0], y) - v
    eps = lfilter(m.D, m.C, w)
    return eps, v, w


def prediction_error_jacobian(m: IDPoly, y, u, eps, v, w) -> np.ndarray:
    """``d eps / d theta``, shape (N, d), columns in the order of ``m.parameters`` (module docstring).

    ``eps, v, w`` are those of :func:`prediction_errors` at ``m``.
    """
    N = y.size
    cols = []
    CF = np.convolve(m.C, m.F)
    if m.na:
        zy = lfilter(m.D, m.C, y)
        cols += [_shift(zy, k) for k in range(1, m.na + 1)]
    if m.nb:
        zu = lfilter(m.D, CF, u)
        cols += [-_shift(zu, m.nk + j) for j in range(m.nb)]
    if m.nc:
        ze = lfilter([1.0], m.C, eps)
        cols += [-_shift(ze, k) for k in range(1, m.nc + 1)]
    if m.nd:
        zw = lfilter([1.0], m.C, w)
        cols += [_shift(zw, k) for k in range(1, m.nd + 1)]
    if m.nf:
        zv = lfilter(m.D, CF, v)
        cols += [_shift(zv, k) for k in range(1, m.nf + 1)]
    return np.column_stack(cols) if cols else np.zeros((N, 0))


def _noise_stable(m: IDPoly) -> bool:
    return is_stable_poly(m.C) and is_stable_poly(m.D) and is_stable_poly(m.F)


def _lm(m: IDPoly, y, u, max_iter: int, tol: float):
    """Levenberg–Marquardt on the prediction error; returns model, J, eps, info."""
    eps, v, w = prediction_errors(m, y, u)
    V = float(eps @ eps)
    mu = 1e-3
    it = 0
    for it in range(1, max_iter + 1):
        J = prediction_error_jacobian(m, y, u, eps, v, w)
        JTJ = J.T @ J
        g = J.T @ eps
        diag = np.diag(JTJ).copy()
        diag[diag <= 0] = 1.0
        improved = False
        for _ in range(20):
            try:
                step = -np.linalg.solve(JTJ + mu * np.diag(diag), g)
            except np.linalg.LinAlgError:
                mu *= 10
                continue
            cand = m.with_parameters(m.parameters + step)
            if _noise_stable(cand):
                e2, v2, w2 = prediction_errors(cand, y, u)
                V2 = float(e2 @ e2)
                if np.isfinite(V2) and V2 <= V:
                    improved = True
                    break
            mu *= 10
        if not improved:
            break
        rel = (V - V2) / max(V, 1e-300)
        m, eps, v, w, V = cand, e2, v2, w2, V2
        mu = max(mu / 10, 1e-12)
        if rel < tol and np.linalg.norm(step) <= 1e-6 * (1 + np.linalg.norm(m.parameters)):
            break
        if rel < tol * 1e-3:
            break
    J = prediction_error_jacobian(m, y, u, eps, v, w)
    return m, J, eps, dict(iterations=it, cost=V)


# ------------------------------------------------------------- start values
def _hannan_rissanen(y, u, na, nb, nc, nk, use_input=True):
    """LS on [y lags, u lags, residual lags of a long ARX]; returns (A, B, C)."""
    N = y.size
    n_hi = int(min(max(2 * (na + nb + nc), 20), max(N // 10, na + nb + nc + 1)))
    if use_input and nb:
        Phi, tgt, n0 = arx_regressors(y, u, n_hi, n_hi, 1)
    else:
        Phi, tgt, n0 = arx_regressors(y, u, n_hi, 0, 1)
    th, *_ = qr_lstsq(Phi, tgt)
    e = np.zeros(N)
    e[n0:] = tgt - Phi @ th
    Phi2, tgt2, n1 = arx_regressors(y, u, na, nb, nk)
    cols = [Phi2]
    if nc:
        E = np.column_stack([_shift(e, k) for k in range(1, nc + 1)])
        cols.append(E[n1:])
    X = np.column_stack(cols)
    skip = min(n0, X.shape[0] - X.shape[1] - 1) if nc else 0
    th2, *_ = qr_lstsq(X[skip:], tgt2[skip:])
    A = np.r_[1.0, th2[:na]]
    B = np.zeros(nk + nb)
    B[nk:] = th2[na:na + nb]
    C = reflect_roots(np.r_[1.0, th2[na + nb:]])
    return A, B, C


def steiglitz_mcbride(y, u, nb, nf, nk, iterations=8):
    """Output-error start ``(B, F)`` by Steiglitz–McBride iterations (``F`` reflected to be stable).

    Each iteration filters ``y`` and ``u`` by ``1/F`` and solves the ARX problem
    ``F y_f = B u_f`` by least squares; it stops when ``F`` no longer changes.
    """
    F = np.ones(1)
    B = np.zeros(nk + nb)
    for _ in range(iterations):
        yf = lfilter([1.0], F, y)
        uf = lfilter([1.0], F, u)
        Phi, tgt, _ = arx_regressors(yf, uf, nf, nb, nk)
        th, *_ = qr_lstsq(Phi, tgt)
        Fn = reflect_roots(np.r_[1.0, th[:nf]])
        B = np.zeros(nk + nb)
        B[nk:] = th[nf:]
        if np.allclose(Fn, F, atol=1e-10):
            F = Fn
            break
        F = Fn
    return B, F


class PEM:
    """General polynomial prediction-error estimator.

    Parameters
    ----------
    na, nb, nc, nd, nf, nk : int
        Orders (MATLAB meaning); ``nb >= 1``.
    max_iter : int
        Maximum Levenberg–Marquardt iterations.
    tol : float
        Relative cost decrease below which the search stops.
    init_sys : IDPoly, optional
        Start model with these orders; its ``C``, ``D``, ``F`` must be stable.
    """

    structure = "poly"

    def __init__(self, na=0, nb=1, nc=0, nd=0, nf=0, nk=1, max_iter=50, tol=1e-9, init_sys=None):
        self.na, self.nb, self.nc, self.nd, self.nf, self.nk = na, nb, nc, nd, nf, nk
        self.max_iter = max_iter
        self.tol = tol
        self.init_sys = init_sys

    def _orders(self):
        o = [check_order(getattr(self, n), n, 1 if n == "nb" else 0)
             for n in ("na", "nb", "nc", "nd", "nf", "nk")]
        return o

    def _initial(self, data):
        na, nb, nc, nd, nf, nk = self._orders()
        y, u = data.y, data.u
        if nf or nd:
            B, F = steiglitz_mcbride(y, u, nb, nf, nk) if nf else (None, np.ones(1))
            if B is None:
                _, B, _ = _hannan_rissanen(y, u, 0, nb, 0, nk)
            w = y - lfilter(B, F, u)
            if na:
                A, _, _ = _hannan_rissanen(y, u, na, nb, 0, nk)
            else:
                A = np.ones(1)
            if nc or nd:
                Dp, _, C = _hannan_rissanen(w, u, nd, 0, nc, 1, use_input=False)
                D = reflect_roots(Dp)
            else:
                C, D = np.ones(1), np.ones(1)
            return IDPoly(A, B, C, D, F, Ts=data.Ts, nk=nk, nb=nb)
        A, B, C = _hannan_rissanen(y, u, na, nb, nc, nk)
        return IDPoly(A, B, C, Ts=data.Ts, nk=nk, nb=nb)

    @one_blas_thread
    def fit(self, data: IDData) -> IDPoly:
        """Estimate the model; sets ``model_`` and returns it (an :class:`IDPoly`)."""
        data = check_data(data)
        na, nb, nc, nd, nf, nk = self._orders()
        d = na + nb + nc + nd + nf
        nmax = max(na, nb + nk, nc, nd, nf)
        check_enough_data(data.N - nmax, d, f"{self.structure.upper()} with {d} parameters")
        original = data
        data, sy, su = scaled(data)
        if self.init_sys is not None:
            m0 = self.init_sys
            if not isinstance(m0, IDPoly):
                raise SysidError(f"init_sys must be an IDPoly, got {type(m0).__name__}.")
            if (m0.na, m0.nb, m0.nc, m0.nd, m0.nf, m0.nk) != (na, nb, nc, nd, nf, nk):
                raise SysidError(f"init_sys must have orders na={na} nb={nb} nc={nc} nd={nd} nf={nf} nk={nk}, "
                                 f"got {m0.orders}.")
            for name in "CDF":
                if not is_stable_poly(getattr(m0, name)):
                    r = np.max(np.abs(np.roots(getattr(m0, name))))
                    raise SysidError(f"init_sys must have a stable {name} polynomial (all roots inside the unit "
                                     f"circle), but a root has |z| = {r:.4g}.")
            m0 = IDPoly(m0.A, m0.B * (su / sy), m0.C, m0.D, m0.F, Ts=data.Ts, nk=nk, nb=nb)
        else:
            m0 = self._initial(data)
        m, J, eps, info = _lm(m0, data.y, data.u, check_order(self.max_iter, "max_iter"),
                              check_tolerance(self.tol, "tol"))
        N = data.N
        V = info["cost"]
        lam = V / max(N - d, 1)
        try:
            cov = lam * np.linalg.inv(J.T @ J)
        except np.linalg.LinAlgError:
            cov = np.full((d, d), np.nan)
        model = IDPoly(m.A, m.B, m.C, m.D, m.F, Ts=data.Ts, nk=nk, nb=nb, noise_variance=lam,
                       covariance=cov, structure=self.structure, loss=V / N, n_samples=N,
                       report=info)
        unscale_poly(model, sy, su)
        finish(model, original, f"{self.structure.upper()} model")
        self.model_ = model
        return model


class ARMAX(PEM):
    """ARMAX estimator ``A y = B u + C e``: ``ARMAX(na, nb, nc, nk).fit(data)``."""

    structure = "armax"

    def __init__(self, na, nb, nc, nk=1, max_iter=50, tol=1e-9, init_sys=None):
        super().__init__(na=na, nb=nb, nc=nc, nk=nk, max_iter=max_iter, tol=tol, init_sys=init_sys)


class OE(PEM):
    """Output-error estimator ``y = B/F u + e``: ``OE(nb, nf, nk).fit(data)``."""

    structure = "oe"

    def __init__(self, nb, nf, nk=1, max_iter=50, tol=1e-9, init_sys=None):
        super().__init__(nb=nb, nf=nf, nk=nk, max_iter=max_iter, tol=tol, init_sys=init_sys)


class BJ(PEM):
    """Box–Jenkins estimator ``y = B/F u + C/D e``: ``BJ(nb, nc, nd, nf, nk).fit(data)``."""

    structure = "bj"

    def __init__(self, nb, nc, nd, nf, nk=1, max_iter=50, tol=1e-9, init_sys=None):
        super().__init__(nb=nb, nc=nc, nd=nd, nf=nf, nk=nk, max_iter=max_iter, tol=tol, init_sys=init_sys)


def armax(data: IDData, orders, init_sys=None) -> IDPoly:
    """MATLAB ``armax(data, [na nb nc nk])``; returns an :class:`IDPoly`."""
    na, nb, nc, nk = check_orders(orders, ("na", "nb", "nc", "nk"), (0, 1, 0, 0))
    return ARMAX(na, nb, nc, nk, init_sys=init_sys).fit(data)


def oe(data: IDData, orders, init_sys=None) -> IDPoly:
    """MATLAB ``oe(data, [nb nf nk])``; returns an :class:`IDPoly`."""
    nb, nf, nk = check_orders(orders, ("nb", "nf", "nk"), (1, 0, 0))
    return OE(nb, nf, nk, init_sys=init_sys).fit(data)


def bj(data: IDData, orders, init_sys=None) -> IDPoly:
    """MATLAB ``bj(data, [nb nc nd nf nk])``; returns an :class:`IDPoly`."""
    nb, nc, nd, nf, nk = check_orders(orders, ("nb", "nc", "nd", "nf", "nk"), (1, 0, 0, 0, 0))
    return BJ(nb, nc, nd, nf, nk, init_sys=init_sys).fit(data)


def pem(data: IDData, init_sys: IDPoly) -> IDPoly:
    """MATLAB ``pem(data, init_sys)``: refine a polynomial model of any structure."""
    if not isinstance(init_sys, IDPoly):
        raise SysidError(f"init_sys must be an IDPoly, got {type(init_sys).__name__}.")
    o = init_sys.orders
    est = PEM(init_sys=init_sys, **o)
    est.structure = init_sys.structure
    return est.fit(data)
