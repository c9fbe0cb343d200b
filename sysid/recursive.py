"""Recursive least squares (RLS) for ARX and extended least squares for ARMAX.

The recursion is eq. (8) of the online-identification paper
(``/work/shared/papers/mixed-reality-online-identification.md``)::

    eps   = y(t) - psi^T theta
    theta <- theta + P psi eps / (lambda + psi^T P psi)
    P     <- (P - P psi psi^T P / (lambda + psi^T P psi)) / lambda

with ``P(0) = c I``, forgetting factor ``lambda`` and regressor
``psi(t) = [-y(t-1) .. -y(t-na), u(t-nk) .. u(t-nk-nb+1), e(t-1) .. e(t-nc)]``.
For ARMAX (``nc > 0``) ``e`` are the a-posteriori residuals
``y(t) - psi^T theta(t)`` (extended least squares, Ljung 1999 sec. 11.7).

Uncertainty: the exponentially weighted loss ``V(t) = lambda V(t-1) + eps(t) epsbar(t)``
(``epsbar`` the a-posteriori residual) is kept alongside; with
``Neff = sum_k lambda^k`` and ``f = (1 + lambda^t)/(1 + lambda)`` the noise
variance is ``sigma^2 = V / (Neff - d f)`` and ``cov(theta) = sigma^2 f P``
(exact least-squares covariance for ``lambda = 1``; for ``lambda < 1`` under
stationary regressors).

Implementation note: to keep one ``update`` to a handful of BLAS calls,
``theta`` and ``Q = lambda^t P`` are stored side by side in one Fortran
array ``M = [Q | theta]`` and updated with a single rank-one ``dger`` call;
``P = Q / lambda^t`` is recovered on access and ``Q`` is renormalised before
``lambda^t`` underflows.  This is algebraically identical to eq. (8).
"""
from __future__ import annotations

import numbers
from collections import deque

import numpy as np
from scipy.linalg.blas import dger

from ._checks import check_data, check_forgetting, check_orders
from .data import IDData
from .errors import SysidError
from .polynomial import IDPoly, std_of

_dot = np.dot

__all__ = ["RecursiveARX", "RecursiveARMAX", "RLSResult", "rls"]


class RecursiveARX:
    """Online RLS estimator of an ARX (or, with ``nc > 0``, ARMAX) model.

    Parameters
    ----------
    orders : sequence of int
        ``[na, nb, nk]`` (ARX) or ``[na, nb, nc, nk]`` (ARMAX, extended LS).
    forgetting : float
        Forgetting factor ``lambda`` in (0, 1]; the memory is about
        ``1 / (1 - lambda)`` samples.
    initial_covariance : float
        ``c`` in ``P(0) = c I`` (> 0; the paper uses 100 < c < 10 000).  It acts as a
        prior ``|theta|^2 / c`` that is forgotten like old data; with ``forgetting = 1``
        it never fades and biases ``theta`` by about ``P theta / c``, so use a large
        ``c`` (e.g. 1e8) without forgetting.
    initial_parameters : array_like, shape (d,), optional
        ``theta(0)``; zeros by default.
    Ts : float
        Sample time in seconds, used only for the returned :class:`IDPoly`.

    Examples
    --------
    >>> est = RecursiveARX([2, 2, 1], forgetting=0.99, initial_covariance=1000.0)
    >>> for yk, uk in zip(y, u):          # doctest: +SKIP
    ...     est.update(yk, uk)
    >>> est.parameters                    # doctest: +SKIP
    """

    def __init__(self, orders, forgetting: float = 1.0, initial_covariance: float = 1000.0,
                 initial_parameters=None, Ts: float = 1.0):
        orders = list(orders) if np.iterable(orders) else orders
        if np.iterable(orders) and len(orders) == 4:
            na, nb, nc, nk = check_orders(orders, ("na", "nb", "nc", "nk"), (0, 0, 0, 0))
        else:
            na, nb, nk = check_orders(orders, ("na", "nb", "nk"), (0, 0, 0))
            nc = 0
        d = na + nb + nc
        if d == 0:
            raise SysidError("orders must give at least one parameter, got na = nb = nc = 0.")
        lam = check_forgetting(forgetting)
        try:
            c = float(initial_covariance)
        except (TypeError, ValueError):
            c = float("nan")
        if not (np.isfinite(c) and c > 0):
            raise SysidError(f"initial_covariance must be a positive number c (P0 = c I), got {initial_covariance!r}.")
        self.na, self.nb, self.nc, self.nk, self.d = na, nb, nc, nk, d
        self.forgetting = lam
        self.initial_covariance = c
        self.Ts = Ts
        self._M = np.zeros((d, d + 1), order="F")
        self._M[:, :d] = c * np.eye(d)
        if initial_parameters is not None:
            th = np.asarray(initial_parameters, dtype=float).ravel()
            if th.size != d:
                raise SysidError(f"initial_parameters must have {d} entries, got {th.size}.")
            self._M[:, d] = th
        self._s = 1.0
        self._V = 0.0
        self._psi = np.zeros(d)
        self._MT = self._M.T
        self._udelay = deque([0.0] * nk)  # u(t-1) .. u(t-nk), most recent first
        self.n_updates = 0

    # ------------------------------------------------------------------ online
    def update(self, y: float, u: float) -> float:
        """Process one sample ``(y(t), u(t))``; return the prior error ``y - psi^T theta``.

        Parameters
        ----------
        y : float
            Output at time t.
        u : float
            Input at time t (used now if ``nk = 0``, otherwise delayed).
        """
        try:
            bad = y - y != 0.0 or u - u != 0.0  # NaN or +-inf, checked before any state changes
        except (TypeError, ValueError):        # not a number (str, None, a vector): say which
            raise SysidError(_not_a_sample(y, u, self.n_updates)) from None
        if bad:
            raise SysidError(f"update needs finite y and u, got y = {y!r}, u = {u!r} "
                             f"(sample {self.n_updates}); the estimate is unchanged.")
        psi = self._psi
        na, nb = self.na, self.nb
        # input part of the regressor: u(t-nk) becomes the newest entry
        if nb:
            if self.nk:
                ud = self._udelay
                ud.appendleft(u)
                u = ud.pop()
            if nb > 1:
                psi[na + 1:na + nb] = psi[na:na + nb - 1]
            psi[na] = u
        M = self._M
        d = self.d
        v = _dot(self._MT, psi)            # [Q psi ; theta^T psi]
        k = v[:d]
        lam = self.forgetting
        s = self._s * lam
        den = s + psi.dot(k)
        eps = y - v[d]
        v[d] = -eps
        dger(-1.0 / den, k, v, a=M, overwrite_a=1)
        post = eps * s / den               # a-posteriori residual y - psi^T theta(t)
        self._V = lam * self._V + eps * post
        n = self.n_updates + 1
        self.n_updates = n
        if not n & 7:
            # dger's rounding is not symmetric; an asymmetric part of P grows
            # like lambda^-t (Verhaegen 1989), so restore symmetry every 8 samples
            Q = M[:, :d]
            Q += Q.T
            Q *= 0.5
            if s < 1e-150:
                Q *= 1.0 / s
                s = 1.0
        self._s = s
        # shift in the new output (and residual) for the next sample
        if na:
            if na > 1:
                psi[1:na] = psi[:na - 1]
            psi[0] = -y
        nc = self.nc
        if nc:
            j = na + nb
            if nc > 1:
                psi[j + 1:j + nc] = psi[j:j + nc - 1]
            psi[j] = post
        return float(eps)

    def partial_fit(self, data: IDData) -> "RecursiveARX":
        """Run :meth:`update` over every sample of ``data``; return ``self``."""
        data = check_data(data)
        for yk, uk in zip(data.y.tolist(), data.u.tolist()):
            self.update(yk, uk)
        return self

    # --------------------------------------------------------------- results
    @property
    def parameters(self) -> np.ndarray:
        """Current ``theta = [a_1.., b_nk.., c_1..]``, shape (d,) (a copy)."""
        return self._M[:, self.d].copy()

    @property
    def P(self) -> np.ndarray:
        """Current ``P`` matrix, shape (d, d) (a copy)."""
        return self._M[:, :self.d] / self._s

    def _weights(self):
        """``(Neff, f)``: effective number of samples and ``(1 + lambda^t)/(1 + lambda)``."""
        lam, n = self.forgetting, self.n_updates
        if lam == 1.0:
            return float(n), 1.0
        lt = lam ** n
        return (1.0 - lt) / (1.0 - lam), (1.0 + lt) / (1.0 + lam)

    @property
    def noise_variance(self) -> float:
        """Estimated innovation variance ``V / (Neff - d f)`` (output units squared; NaN until ``Neff > d f``)."""
        neff, f = self._weights()
        dof = neff - self.d * f
        return self._V / dof if dof > 0 else float("nan")

    @property
    def covariance(self) -> np.ndarray:
        """Estimated covariance of :attr:`parameters`, ``sigma^2 f P``, shape (d, d)."""
        _, f = self._weights()
        return self.noise_variance * f * self.P

    @property
    def std(self) -> np.ndarray:
        """Standard deviations of :attr:`parameters`, shape (d,)."""
        return std_of(self.covariance)

    def to_idpoly(self) -> IDPoly:
        """Current estimate as an :class:`IDPoly` (ARX or ARMAX) with its covariance."""
        th = self.parameters
        na, nb, nc, nk = self.na, self.nb, self.nc, self.nk
        B = np.zeros(nk + nb)
        B[nk:] = th[na:na + nb]
        sigma2 = self.noise_variance
        ok = np.isfinite(sigma2)
        return IDPoly(np.r_[1.0, th[:na]], B, np.r_[1.0, th[na + nb:]], Ts=self.Ts, nk=nk, nb=nb,
                      structure="armax" if nc else "arx", noise_variance=sigma2 if ok else 0.0,
                      covariance=self.covariance if ok else None, n_samples=self.n_updates)


def _not_a_sample(y, u, n: int) -> str:
    for name, v in (("y", y), ("u", u)):
        if isinstance(v, (bool, np.bool_)) or not (isinstance(v, (numbers.Real, np.number)) or
                                                   (isinstance(v, np.ndarray) and v.size == 1
                                                    and np.issubdtype(v.dtype, np.number))):
            return (f"update: {name} must be one real number (the sample at time t), got {v!r} "
                    f"({type(v).__name__}) at sample {n}; the estimate is unchanged.")
    return f"update needs two real numbers y and u, got y = {y!r}, u = {u!r} at sample {n}; the estimate is unchanged."


RecursiveARMAX = RecursiveARX
"""Alias: ``RecursiveARMAX([na, nb, nc, nk], ...)`` runs extended least squares."""


class RLSResult:
    """Result of :func:`rls` on a whole record.

    Attributes
    ----------
    theta_ : ndarray, shape (d,)
        Final parameter vector ``[a.., b.., c..]``.
    theta_history : ndarray, shape (N, d)
        ``theta`` after each sample (also ``theta_history_``).
    errors_ : ndarray, shape (N,)
        Prior (one-step) prediction errors.
    model_ : IDPoly
        Final estimate as a polynomial model (with ``covariance``).
    noise_variance : float
        Estimated innovation variance (see :attr:`RecursiveARX.noise_variance`).
    std : ndarray, shape (d,)
        Standard deviations of ``theta_`` (see :attr:`RecursiveARX.covariance`).
    estimator_ : RecursiveARX
        The estimator, ready to continue online with ``update``.
    """

    def __init__(self, estimator, history, errors):
        self.estimator_ = estimator
        self.theta_history = history
        self.theta_history_ = history
        self.errors_ = errors
        self.theta_ = history[-1].copy()
        self.model_ = estimator.to_idpoly()
        self.noise_variance = estimator.noise_variance
        self.covariance = estimator.covariance
        self.std = estimator.std

    @property
    def model(self) -> IDPoly:
        return self.model_


def rls(data: IDData, orders, forgetting: float = 1.0, initial_covariance: float = 1000.0,
        initial_parameters=None) -> RLSResult:
    """Recursive least squares over a whole record, keeping the parameter history.

    Parameters
    ----------
    data : IDData
    orders : sequence of int
        ``[na, nb, nk]`` (ARX) or ``[na, nb, nc, nk]`` (ARMAX by extended LS).
    forgetting : float
        ``lambda`` in (0, 1].
    initial_covariance : float
        ``c`` in ``P0 = c I``.
    initial_parameters : array_like, optional
        ``theta(0)``.

    Returns
    -------
    RLSResult
        With ``theta_``, ``theta_history`` (N, d), ``errors_`` and ``model_``.
    """
    data = check_data(data)
    est = RecursiveARX(orders, forgetting, initial_covariance, initial_parameters, Ts=data.Ts)
    N = data.N
    hist = np.empty((N, est.d))
    errs = np.empty(N)
    M, d, upd = est._M, est.d, est.update
    for t, (yk, uk) in enumerate(zip(data.y.tolist(), data.u.tolist())):
        errs[t] = upd(yk, uk)
        hist[t] = M[:, d]
    res = RLSResult(est, hist, errs)
    from ._diagnose import finish
    finish(res.model_, data, "final RLS model")   # says so when the last estimate is unstable or B = 0
    return res
