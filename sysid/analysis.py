"""Model validation and structure selection: resid, aic/fpe/bic, arxstruc/selstruc, delayest.

Information criteria follow MATLAB (``aic``, ``fpe``, ``bic`` of the System
Identification Toolbox) for one output, with ``V = sum(eps^2)/N`` the loss on
the estimation data, ``d`` the number of parameters and ``N`` the number of
samples used::

    FPE = V (1 + d/N) / (1 - d/N)
    AIC = N log V + 2 d + N (log(2 pi) + 1)
    BIC = N log V + d log N + N (log(2 pi) + 1)
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ._blas import one_blas_thread
from ._checks import check_data, check_enough_data, check_order
from .arx import ARX, arx_regressors
from .data import IDData
from .errors import SysidError
from .linalg import qr_lstsq
from .predict import predict

__all__ = ["ResidResult", "resid", "aic", "fpe", "bic", "struc", "arxstruc", "selstruc", "delayest"]

_Z99 = 2.5758293035489004  # two-sided 99 % normal quantile


@dataclass
class ResidResult:
    """Residual analysis (MATLAB ``resid``).

    Attributes
    ----------
    residuals : ndarray, shape (N,)
        One-step prediction errors ``y - y_hat(t|t-1)``.
    lags : ndarray, shape (M+1,)
        ``0 .. M`` for the autocorrelation.
    autocorr : ndarray, shape (M+1,)
        Normalised autocorrelation of the residuals (``autocorr[0] = 1``).
    cross_lags : ndarray, shape (2M+1,)
        ``-M .. M`` for the cross-correlation (positive lag: input leads).
    crosscorr : ndarray, shape (2M+1,)
        Normalised cross-correlation between residuals and past inputs.
    bound : float
        99 % confidence bound ``2.58 / sqrt(N)`` for both (white, independent residuals).
    """

    residuals: np.ndarray
    lags: np.ndarray
    autocorr: np.ndarray
    cross_lags: np.ndarray
    crosscorr: np.ndarray
    bound: float

    @property
    def white(self) -> bool:
        """True when all autocorrelations at lags 1..M lie inside the 99 % bound."""
        return bool(np.all(np.abs(self.autocorr[1:]) < self.bound))

    @property
    def independent(self) -> bool:
        """True when all cross-correlations lie inside the 99 % bound."""
        return bool(np.all(np.abs(self.crosscorr) < self.bound))


def _xcorr(a, b, lag):
    """sum_t a(t+lag) b(t) / N for lag >= 0."""
    N = a.size
    return float(a[lag:] @ b[:N - lag]) / N


def resid(data: IDData, model, max_lag: int = 25, skip: int = 0) -> ResidResult:
    """Residual whiteness and independence test with 99 % bounds (MATLAB ``resid``).

    Parameters
    ----------
    data : IDData
        Validation data.
    model : IDPoly, IDSS or IDTF
    max_lag : int
        Largest lag ``M`` in samples.
    skip : int
        Samples dropped at the start before the correlations are computed.
        Predictions start from zero initial conditions, so a record that does
        not start at rest shows a transient there; skip it.
    """
    data = check_data(data)
    M = check_order(max_lag, "max_lag", 1)
    if M >= data.N // 2:
        raise SysidError(f"max_lag must be below N/2 = {data.N // 2}, got {M}.")
    skip = check_order(skip, "skip")
    if skip > data.N - 2 * M - 2:
        raise SysidError(f"skip must leave more than 2*max_lag samples, got skip = {skip} for N = {data.N}.")
    e = (data.y - predict(model, data, 1))[skip:]
    u = data.u[skip:] - data.u[skip:].mean()
    re0 = _xcorr(e, e, 0)
    ru0 = _xcorr(u, u, 0)
    if re0 <= 0:
        raise SysidError("model reproduces the output exactly; residual correlations are undefined.")
    ac = np.array([_xcorr(e, e, k) for k in range(M + 1)]) / re0
    scale = math.sqrt(re0 * ru0) if ru0 > 0 else 1.0
    cc = np.array([_xcorr(e, u, k) if k >= 0 else _xcorr(u, e, -k) for k in range(-M, M + 1)]) / scale
    return ResidResult(e, np.arange(M + 1), ac, np.arange(-M, M + 1), cc, _Z99 / math.sqrt(e.size))


def _loss_terms(model, data):
    if data is not None:
        data = check_data(data)
        e = data.y - predict(model, data, 1)
        return float(e @ e) / data.N, data.N
    V, N = getattr(model, "loss", float("nan")), getattr(model, "n_samples", 0)
    if not (N and np.isfinite(V)):
        raise SysidError("model carries no estimation loss; pass the estimation data as data=.")
    return V, N


def _n_params(model):
    n = getattr(model, "n_parameters", None)
    if n is None:
        raise SysidError(f"model must be an estimated IDPoly, IDSS or IDTF, got {type(model).__name__}.")
    return n


def _log(V: float) -> float:
    """``log V`` with ``log 0 = -inf`` (a model that reproduces the data exactly, as MATLAB)."""
    return math.log(V) if V > 0 else -math.inf


def fpe(model, data: IDData | None = None) -> float:
    """Akaike's final prediction error ``V (1 + d/N)/(1 - d/N)``; needs ``N > d``."""
    V, N = _loss_terms(model, data)
    d = _n_params(model)
    if not N > d:
        raise SysidError(f"model has {d} parameters for {N} samples: FPE needs more samples than parameters.")
    return V * (1 + d / N) / (1 - d / N)


def aic(model, data: IDData | None = None) -> float:
    """Raw Akaike information criterion ``N log V + 2d + N(log 2pi + 1)`` (MATLAB ``aic``)."""
    V, N = _loss_terms(model, data)
    return N * _log(V) + 2 * _n_params(model) + N * (math.log(2 * math.pi) + 1)


def bic(model, data: IDData | None = None) -> float:
    """Bayesian information criterion ``N log V + d log N + N(log 2pi + 1)``."""
    V, N = _loss_terms(model, data)
    return N * _log(V) + _n_params(model) * math.log(N) + N * (math.log(2 * math.pi) + 1)


def struc(na_range, nb_range, nk_range) -> np.ndarray:
    """All ``[na, nb, nk]`` combinations (MATLAB ``struc``), shape (n, 3)."""
    return np.array(list(itertools.product(na_range, nb_range, nk_range)), dtype=int)


@one_blas_thread
def arxstruc(estimation: IDData, validation: IDData, orders) -> np.ndarray:
    """Loss of ARX models over a grid (MATLAB ``arxstruc``).

    Parameters
    ----------
    estimation, validation : IDData
    orders : array_like of int, shape (n, 3)
        Rows ``[na, nb, nk]`` (see :func:`struc`).

    Returns
    -------
    ndarray, shape (n, 5)
        Rows ``[V, na, nb, nk, N]``: the mean squared one-step prediction error on
        ``validation`` (regression samples only) and the number of samples used.
    """
    estimation, validation = check_data(estimation, "estimation"), check_data(validation, "validation")
    orders = np.atleast_2d(np.asarray(orders))
    if orders.ndim != 2 or orders.shape[1] != 3:
        raise SysidError(f"orders must have rows [na, nb, nk], got shape {orders.shape}.")
    rows = []
    for row in orders.tolist():
        row = [int(v) if isinstance(v, float) and v.is_integer() else v for v in row]   # a float array's 2.0
        na, nb, nk = (check_order(v, name) for v, name in zip(row, ("na", "nb", "nk")))
        check_enough_data(validation.N - max(na, nk + nb - 1, 0), na + nb, f"validation of ARX[{na} {nb} {nk}]")
        m = ARX(na, nb, nk)._fit(estimation, strict=False)  # a grid may hold degenerate orders
        Phi, tgt, _ = arx_regressors(validation.y, validation.u, na, nb, nk)
        r = tgt - Phi @ m.parameters
        rows.append([float(r @ r) / r.size, na, nb, nk, r.size])
    return np.array(rows)


def selstruc(table: np.ndarray, criterion: str = "val") -> list[int]:
    """Pick ``[na, nb, nk]`` from an :func:`arxstruc` table (MATLAB ``selstruc``).

    Parameters
    ----------
    table : ndarray, shape (n, 5)
    criterion : {"val", "aic", "mdl"}
        ``"val"``: smallest loss (use with separate validation data);
        ``"aic"``: ``V (1 + 2d/N)``; ``"mdl"``: ``V (1 + d log(N)/N)`` (MATLAB's forms).
    """
    try:
        t = np.asarray(table, dtype=float)
    except (TypeError, ValueError):
        t = np.zeros(0)
    if t.ndim != 2 or t.shape[0] == 0 or t.shape[1] != 5 or not np.all(np.isfinite(t)):
        raise SysidError(f"table must be an arxstruc table: rows [V, na, nb, nk, N] of finite numbers, got "
                         f"shape {np.shape(table)}.")
    V, d, N = t[:, 0], t[:, 1] + t[:, 2], t[:, 4]
    if criterion == "val":
        score = V
    elif criterion == "aic":
        score = V * (1 + 2 * d / N)
    elif criterion == "mdl":
        score = V * (1 + d * np.log(N) / N)
    else:
        raise SysidError(f"criterion must be 'val', 'aic' or 'mdl', got {criterion!r}.")
    i = int(np.argmin(score))
    return [int(t[i, 1]), int(t[i, 2]), int(t[i, 3])]


@one_blas_thread
def delayest(data: IDData, na: int = 2, nb: int = 2, nk_min: int = 0, nk_max: int = 10) -> int:
    """Input delay in samples: the ``nk`` of the best-fitting ARX[na nb nk] (MATLAB ``delayest``).

    All candidates are compared on the same samples.
    """
    data = check_data(data)
    na, nb = check_order(na, "na"), check_order(nb, "nb", 1)
    nk_min, nk_max = check_order(nk_min, "nk_min"), check_order(nk_max, "nk_max")
    if nk_max < nk_min:
        raise SysidError(f"nk_max must be >= nk_min = {nk_min}, got {nk_max}.")
    n0 = max(na, nk_max + nb - 1)
    check_enough_data(data.N - n0, na + nb, f"delayest with na = {na}, nb = {nb} and nk_max = {nk_max}")
    best, best_nk = np.inf, nk_min
    for nk in range(nk_min, nk_max + 1):
        Phi, tgt, n = arx_regressors(data.y, data.u, na, nb, nk)
        _, rss, _ = qr_lstsq(Phi[n0 - n:], tgt[n0 - n:])
        if rss < best * (1 - 1e-9):
            best, best_nk = rss, nk
    return best_nk
