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

Settings that cannot give an estimate are refused (:func:`check_rls_options`):
a memory ``1/(1 - lambda)`` shorter than ``d + 1`` samples, and, where the
signals are known (:func:`rls`), a ``c`` for which the first update already
cancels every digit of ``P``.  An update that meets ``psi^T P psi >= lambda/eps``
later (``P`` grown in directions the input does not excite) says so once
(:class:`~sysid.SysidWarning`, ``warnings``); one that would overflow is refused
with the estimate unchanged.
"""
from __future__ import annotations

import math
import numbers
import warnings as _warnings
from collections import deque

import numpy as np
from scipy.linalg.blas import dger

from ._checks import check_data, check_enough_data, check_orders, check_tolerance
from .data import IDData, check_sample_time, real_number
from .errors import SysidError, SysidWarning
from .polynomial import IDPoly, std_of

_dot = np.dot

__all__ = ["RecursiveARX", "RecursiveARMAX", "RLSResult", "rls", "check_rls_options", "RLS_DIGITS_LIMIT"]

RLS_DIGITS_LIMIT = 1.0 / np.finfo(float).eps
"""Largest ``psi^T P psi / lambda`` (about 4.5e15) an update may meet.

The covariance update subtracts from ``P`` a matrix that agrees with it to
``log10(psi^T P psi / lambda)`` digits in the direction of ``psi``; at ``1/eps``
nothing of float64's 16 digits is left and ``P`` (hence ``theta``) is rounding.
With ``P(0) = c I`` the first update meets ``c |psi|^2``.
"""


PRIOR_SHARE_LIMIT = 0.01
"""Share of the prior ``P(0) = c I`` in the final weight along some direction above which :func:`rls` says so."""


def _rls_orders(orders) -> tuple[int, int, int, int]:
    """``(na, nb, nc, nk)`` from ``[na, nb, nk]`` or ``[na, nb, nc, nk]``, with at least one parameter."""
    orders = list(orders) if np.iterable(orders) and not isinstance(orders, str) else orders
    if np.iterable(orders) and len(orders) == 4:
        na, nb, nc, nk = check_orders(orders, ("na", "nb", "nc", "nk"), (0, 0, 0, 0))
    else:
        na, nb, nk = check_orders(orders, ("na", "nb", "nk"), (0, 0, 0))
        nc = 0
    if na + nb + nc == 0:
        raise SysidError("orders must give at least one parameter, got na = nb = nc = 0.")
    return na, nb, nc, nk


def check_rls_options(orders, forgetting=1.0, initial_covariance=1000.0, *, max_abs_y=None, max_abs_u=None):
    """Check the settings of a recursive least-squares estimator; return them as numbers.

    The checks of :class:`RecursiveARX` and :func:`rls`, for any caller that runs the
    same recursion (eq. 8) elsewhere, e.g. in a control loop: call it before the first
    sample, so that a bad setting is one :class:`SysidError` naming it instead of a NaN
    or a silently wrong estimate later.

    Parameters
    ----------
    orders : sequence of int
        ``[na, nb, nk]`` or ``[na, nb, nc, nk]``; ``d = na + nb + nc`` parameters.
    forgetting : float
        ``lambda``, in ``[d/(d+1), 1]``: the memory ``1/(1 - lambda)`` (samples) must
        hold at least ``d + 1`` samples, as a batch fit needs more samples than parameters
        (below ``(d-1)/(d+1)`` the noise variance and the covariance are undefined, and
        the recursion overflows for small ``lambda``).
    initial_covariance : float
        ``c`` in ``P(0) = c I``: finite and > 0.
    max_abs_y, max_abs_u : float, optional
        Largest ``|y|`` and ``|u|`` the estimator will see (output and input units, finite, >= 0).  With
        them ``c`` is also checked against the signals: ``c |psi|^2`` with ``|psi|^2`` up to
        ``(na + nc) max_abs_y^2 + nb max_abs_u^2`` must stay below ``lambda / eps``
        (:data:`RLS_DIGITS_LIMIT`), else the first update leaves no correct digit in ``P``.

    Returns
    -------
    (na, nb, nc, nk), forgetting, initial_covariance : tuple of int, float, float

    Raises
    ------
    SysidError
        One sentence naming the argument and the range expected.
    """
    na, nb, nc, nk = _rls_orders(orders)
    d = na + nb + nc
    low = d / (d + 1.0)
    lam = real_number(forgetting, "forgetting", f"a number in [{low:.4g}, 1]")
    if not low <= lam <= 1.0:
        raise SysidError(f"forgetting must be in [{low:.4g}, 1] for {d} parameters (its memory 1/(1 - forgetting) "
                         f"must hold at least d + 1 = {d + 1} samples), got {forgetting!r}.")
    c = real_number(initial_covariance, "initial_covariance", "a positive number c (P0 = c I)")
    if not (math.isfinite(c) and c > 0):
        raise SysidError(f"initial_covariance must be a positive finite number c (P0 = c I), got "
                         f"{initial_covariance!r}.")
    if max_abs_y is not None or max_abs_u is not None:
        ymax = check_tolerance(0.0 if max_abs_y is None else max_abs_y, "max_abs_y")
        umax = check_tolerance(0.0 if max_abs_u is None else max_abs_u, "max_abs_u")
        psi2 = (na + nc) * ymax * ymax + nb * umax * umax      # Python floats: inf, not an error, when too large
        if not math.isfinite(psi2):
            raise SysidError(
                f"signals up to |y| = {ymax:.4g} and |u| = {umax:.4g} are too large for recursive least squares "
                f"in float64 (|psi|^2 up to {psi2:.3g}: no initial_covariance keeps c |psi|^2 below "
                f"forgetting/eps); express y and u in units nearer 1.")
        if not c * psi2 < lam * RLS_DIGITS_LIMIT:
            raise SysidError(
                f"initial_covariance c = {c:.4g} is too large for signals up to |y| = {ymax:.4g} and "
                f"|u| = {umax:.4g}: c |psi|^2 = {c * psi2:.3g} must stay below forgetting/eps = "
                f"{lam * RLS_DIGITS_LIMIT:.3g}, beyond which the first update leaves no correct digit in P "
                f"(expected c < {lam * RLS_DIGITS_LIMIT / psi2:.3g}).")
    return (na, nb, nc, nk), lam, c


class RecursiveARX:
    """Online RLS estimator of an ARX (or, with ``nc > 0``, ARMAX) model.

    Parameters
    ----------
    orders : sequence of int
        ``[na, nb, nk]`` (ARX) or ``[na, nb, nc, nk]`` (ARMAX, extended LS).
    forgetting : float
        Forgetting factor ``lambda`` in ``[d/(d+1), 1]`` for ``d`` parameters; the memory
        is about ``1 / (1 - lambda)`` samples and must hold at least ``d + 1``.
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
        (na, nb, nc, nk), lam, c = check_rls_options(orders, forgetting, initial_covariance)
        d = na + nb + nc
        self.na, self.nb, self.nc, self.nk, self.d = na, nb, nc, nk, d
        self.forgetting = lam
        self.initial_covariance = c
        self.Ts = check_sample_time(Ts)
        self._M = np.zeros((d, d + 1), order="F")
        self._M[:, :d] = c * np.eye(d)
        if initial_parameters is not None:
            th = _parameters(initial_parameters, d)
            self._M[:, d] = th
        self._s = 1.0
        self._V = 0.0
        self._psi = np.zeros(d)
        self._MT = self._M.T
        self._udelay = deque([0.0] * nk)  # u(t-1) .. u(t-nk), most recent first
        self.n_updates = 0
        self.warnings = []

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
        if type(y) is not float or type(u) is not float:   # ints, NumPy scalars: as floats; else refused
            y, u = _samples(y, u, self.n_updates)
        if y - y != 0.0 or u - u != 0.0:  # NaN or +-inf, checked before any state changes
            raise SysidError(f"update needs finite y and u, got y = {y!r}, u = {u!r} "
                             f"(sample {self.n_updates}); the estimate is unchanged.")
        psi = self._psi
        na, nb = self.na, self.nb
        # input part of the regressor: u(t-nk) becomes the newest entry
        u_now = u
        if nb:
            oldest = psi[na + nb - 1]      # kept to undo the shift if the update is refused
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
        pk = psi.dot(k)                    # lambda^t psi^T P psi
        if not pk < s * RLS_DIGITS_LIMIT:  # no digit of P left, or overflow (inf, NaN)
            if not math.isfinite(pk):
                msg = self._overflow_message(pk, u_now)
                if nb:
                    if self.nk:
                        ud.append(u)
                        ud.popleft()
                    if nb > 1:
                        psi[na:na + nb - 1] = psi[na + 1:na + nb]
                    psi[na + nb - 1] = oldest
                raise SysidError(msg)
            self._precision_lost(pk / self._s)
        den = s + pk
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

    def _overflow_message(self, pk, u_now) -> str:
        psi2 = float(np.dot(self._psi, self._psi))
        return (f"update: psi^T P psi overflows at sample {self.n_updates} ({pk}; |psi|^2 = {psi2:.3g}, largest "
                f"P entry {float(np.max(np.abs(self.P))):.3g}): initial_covariance c = {self.initial_covariance:.4g} "
                f"is too large for these signals, or P grew without excitation; use a smaller c or y, u in units "
                f"nearer 1 (u = {u_now!r} now), the estimate is unchanged.")

    def _precision_lost(self, ratio: float) -> None:
        """Say once that an update met ``psi^T P psi >= lambda / eps`` (P is rounding from here on)."""
        if self.warnings:
            return
        msg = (f"RLS update at sample {self.n_updates} met psi^T P psi = {ratio:.3g}, beyond forgetting/eps = "
               f"{self.forgetting * RLS_DIGITS_LIMIT:.3g}: the covariance update cancels all 16 digits of P along "
               f"psi, so P, theta and their uncertainty are rounding until the data refill them (about "
               f"1/(1 - forgetting) samples with forgetting < 1, never without); use a smaller initial_covariance "
               f"(c = {self.initial_covariance:.4g} now) or y, u in units nearer 1, and with forgetting < 1 keep "
               f"the input exciting (P grows like forgetting^-t in directions the data do not excite).")
        self.warnings.append(msg)
        _warnings.warn(msg, SysidWarning, stacklevel=3)

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


def _samples(y, u, n: int) -> tuple[float, float]:
    """``(y, u)`` as floats when each is one real number (int, NumPy scalar, size-1 real array); else
    :class:`SysidError` naming the first that is not (complex, bool, text, None, a vector)."""
    out = []
    for name, v in (("y", y), ("u", u)):
        if isinstance(v, np.ndarray) and v.size == 1 and v.dtype.kind in "iuf":
            v = v.reshape(()).item()
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
            what = "complex" if isinstance(v, (complex, np.complexfloating)) or (
                isinstance(v, np.ndarray) and v.dtype.kind == "c") else type(v).__name__
            raise SysidError(f"update: {name} must be one real number (the sample at time t), got {v!r} "
                             f"({what}) at sample {n}; the estimate is unchanged.")
        out.append(float(v))
    return out[0], out[1]


def _parameters(theta, d: int) -> np.ndarray:
    """``initial_parameters`` as ``d`` finite real numbers."""
    try:
        a = np.asarray(theta)
        a = a.astype(float).ravel() if a.dtype.kind in "biuf" else None
    except (TypeError, ValueError):
        a = None
    if a is None or a.size != d or not np.all(np.isfinite(a)):
        raise SysidError(f"initial_parameters must be {d} finite real numbers [a.., b.., c..], got {theta!r}.")
    return a


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
        ``lambda`` in ``[d/(d+1), 1]`` for ``d`` parameters (see :func:`check_rls_options`).
    initial_covariance : float
        ``c`` in ``P0 = c I``; ``c |psi|^2`` over the record (``|psi|^2`` bounded by the
        largest ``|y|`` and ``|u|``) must stay below ``forgetting / eps``.
    initial_parameters : array_like, optional
        ``theta(0)``.

    Returns
    -------
    RLSResult
        With ``theta_``, ``theta_history`` (N, d), ``errors_`` and ``model_``.

    Raises
    ------
    SysidError
        For settings :func:`check_rls_options` refuses on this record's signals, and for
        orders with as many parameters as samples.
    """
    data = check_data(data)
    (na, nb, nc, nk), _, _ = check_rls_options(orders, forgetting, initial_covariance,
                                               max_abs_y=float(np.max(np.abs(data.y))),
                                               max_abs_u=float(np.max(np.abs(data.u))))
    check_enough_data(data.N - max(na, nc, nk + nb - 1, 0), na + nb + nc, f"rls with orders {list(orders)}")
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
    res.model_.warnings = est.warnings + res.model_.warnings + _prior_dominates(est, data)
    return res


def _prior_dominates(est: RecursiveARX, data: IDData) -> list[str]:
    """A sentence (issued as a warning) when, along some direction of ``theta``, the prior ``P(0) = c I``
    still holds 1 % or more of the weight at the end, so the estimate there is pulled that far towards
    ``theta(0)``.

    ``P^-1 = sum_s lambda^(t-s) psi psi^T + lambda^t I / c``: along an eigenvector of ``P`` the prior's share
    of the weight is ``P``'s eigenvalue over the prior's own ``c / lambda^t``.
    """
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        prior_only = est.initial_covariance / est.forgetting ** est.n_updates
        P = est.P
        largest = float(np.max(np.linalg.eigvalsh(P))) if np.all(np.isfinite(P)) else float("nan")
    share = largest / prior_only
    if not share >= PRIOR_SHARE_LIMIT:
        return []
    msg = (f"final RLS model: along some direction of the parameters the prior P(0) = c I still holds "
           f"{100 * min(share, 1.0):.3g} % of the weight (c = {est.initial_covariance:.4g}, |y| up to "
           f"{float(np.max(np.abs(data.y))):.3g}, |u| up to {float(np.max(np.abs(data.u))):.3g}), so the estimate is "
           f"pulled that far towards initial_parameters; excite the input more, or use a larger initial_covariance "
           f"for signals of this size.")
    _warnings.warn(msg, SysidWarning, stacklevel=3)
    return [msg]
