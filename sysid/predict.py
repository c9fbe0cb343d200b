"""Prediction, simulation and MATLAB-style ``compare`` fit.

Polynomial and continuous-time models are evaluated through their polynomial
form ``A y = B/F u + C/D e`` (an :class:`~sysid.IDTF` converts itself with
``to_idpoly()``); a state-space :class:`~sysid.IDSS` is evaluated in state
space (:mod:`sysid.state_response`), since the characteristic polynomial of a
high-order ``A`` loses its eigenvalues, so that what is simulated is the model
whose poles ``model.poles()`` and its warnings report.

Initial conditions: ``"zero"`` assumes zero input, output and noise before
the first sample (the default of :func:`simulate` and :func:`predict`, as
MATLAB's ``sim``); ``"estimate"`` (simulation only) chooses the initial
filter state that best fits the measured output in least squares, like
MATLAB's ``InitialCondition='e'``, which is :func:`compare`'s default (as in
MATLAB).

A discrete model is evaluated only on data with its own sample time; a
continuous-time :class:`~sysid.IDTF` is discretised (zero-order hold) at the
data's sample time.  A simulation that overflows (unstable model) raises
:class:`~sysid.SysidError` instead of returning inf.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import fftconvolve, lfilter

from ._checks import check_data
from .data import IDData, as_signal
from .errors import SysidError
from .polynomial import IDPoly
from .state_response import free_response_rows, predict_states, simulate_states
from .statespace import IDSS

__all__ = ["predict", "simulate", "compare", "fit_percent"]

DIRECT_HORIZON = 64
"""Longest horizon (samples) predicted by filtering with the predictor polynomials directly, ``O(N k)``;
longer ones convolve the ``k`` impulse-response terms by FFT, ``O(N log N)`` (equal to rounding)."""


def as_idpoly(model, Ts=None) -> IDPoly:
    """Return the polynomial form of ``model`` (internal).

    With ``Ts`` (the data's sample time, s): a discrete model sampled otherwise is
    refused; a continuous-time model is discretised at ``Ts``.
    """
    if Ts is not None and hasattr(model, "to_lti_continuous"):
        return model.to_idpoly(Ts=Ts)
    if isinstance(model, IDPoly):
        m = model
    else:
        conv = getattr(model, "to_idpoly", None)
        if conv is None:
            raise SysidError(f"model must be a sysid model (IDPoly, IDSS or IDTF), got {type(model).__name__}.")
        m = conv()
    if Ts is not None:
        _check_sample_time(m.Ts, Ts)
    return m


def _check_sample_time(model_Ts: float, data_Ts: float) -> None:
    if not math.isclose(float(model_Ts), float(data_Ts), rel_tol=1e-9):
        raise SysidError(f"model is sampled at Ts = {model_Ts:g} s but the data at Ts = {data_Ts:g} s: resample the "
                         f"data or estimate the model at the data's sample time.")


def _check_parameters_finite(model: IDSS) -> None:
    bad = [name for name in ("A", "B", "C", "D", "K") if not np.all(np.isfinite(getattr(model, name)))]
    if bad:
        raise SysidError(f"model has non-finite entries (inf or NaN) in {', '.join(bad)}: it cannot be simulated "
                         f"or predicted; re-estimate it (see model.warnings).")


def _check_finite_ss(yhat, model: IDSS, what: str):
    """As :func:`_check_finite`, with the eigenvalues the state-space evaluation ran on."""
    if np.all(np.isfinite(yhat)):
        return
    if "prediction" in what:
        r = float(np.max(np.abs(np.linalg.eigvals(model.A - model.K @ model.C))))
        if r >= 1.0:
            raise SysidError(f"the model's predictor is unstable (an eigenvalue of A - K C has |z| = {r:.6g}): its "
                             f"{what} overflows over {yhat.size} samples; use a model with a stable predictor.")
    r = float(np.max(np.abs(model.poles())))
    raise SysidError(f"model is unstable (a pole has |z| = {r:.6g} > 1): its {what} overflows over "
                     f"{yhat.size} samples; use k-step prediction (k=1) or a stable model.")


def _check_finite(yhat, m: IDPoly, what: str):
    if not np.all(np.isfinite(yhat)) and "prediction" in what:
        roots = np.roots(np.trim_zeros(np.convolve(m.C, m.F), "b")) if m.nc + m.nf else np.zeros(0)
        r = float(np.max(np.abs(roots))) if roots.size else float("nan")
        raise SysidError(f"the model's predictor is unstable (a root of C F has |z| = {r:.6g}): its {what} "
                         f"overflows over {yhat.size} samples; use a model with a stable noise model.")
    if not np.all(np.isfinite(yhat)):
        poles = m.poles()
        r = float(np.max(np.abs(poles))) if poles.size else float("nan")
        raise SysidError(f"model is unstable (a pole has |z| = {r:.6g} > 1): its {what} overflows over "
                         f"{yhat.size} samples; use k-step prediction (k=1) or a stable model.")


def _pad(p, n):
    out = np.zeros(n)
    out[:len(p)] = p
    return out


def _free_response_basis(b, a, N):
    n = max(len(a), len(b)) - 1
    basis = np.zeros((N, n))
    x = np.zeros(N)
    for i in range(n):
        zi = np.zeros(n)
        zi[i] = 1.0
        basis[:, i] = lfilter(b, a, x, zi=zi)[0]
    return basis


def simulate(model, data_or_u, initial: str = "zero") -> np.ndarray:
    """Noise-free simulation ``y_s = B/(A F) u``.

    Parameters
    ----------
    model : IDPoly, IDSS or IDTF
    data_or_u : IDData or array_like, shape (N,)
        Input record; an IDData is needed for ``initial="estimate"``.
    initial : {"zero", "estimate"}
        Initial conditions (see module docstring).

    Returns
    -------
    ndarray, shape (N,)
        Simulated output.
    """
    state_space = isinstance(model, IDSS)
    if isinstance(data_or_u, IDData):
        if state_space:
            _check_sample_time(model.Ts, data_or_u.Ts)
        else:
            m = as_idpoly(model, data_or_u.Ts)
        u = data_or_u.u
    else:
        if not state_space:
            m = as_idpoly(model)
        u = as_signal(data_or_u, "u")
    if initial not in ("zero", "estimate"):
        raise SysidError(f"initial must be 'zero' or 'estimate', got {initial!r}.")
    if initial == "estimate" and not isinstance(data_or_u, IDData):
        raise SysidError("initial='estimate' needs an IDData (the measured output is used).")
    if state_space:
        _check_parameters_finite(model)
        return _simulate_ss(model, u, data_or_u.y if initial == "estimate" else None)
    num, den = m.G()
    with np.errstate(over="ignore", invalid="ignore"):
        ys = lfilter(num, den, u)
    _check_finite(ys, m, "simulation")
    if initial == "zero":
        return ys
    with np.errstate(over="ignore", invalid="ignore"):
        basis = _free_response_basis(num, den, u.size)
    _check_finite(basis, m, "free response")
    if basis.shape[1]:
        norms = np.sqrt(np.einsum("ij,ij->j", basis, basis))
        norms[norms == 0] = 1.0
        x0, *_ = np.linalg.lstsq(basis / norms, data_or_u.y - ys, rcond=None)
        ys = ys + (basis / norms) @ x0
    return ys


def _simulate_ss(model: IDSS, u, y=None) -> np.ndarray:
    """Simulation of an IDSS in state space; with ``y``, plus the least-squares initial state's response."""
    with np.errstate(over="ignore", invalid="ignore"):
        ys = simulate_states(model.A, model.B, model.C, model.D, u)
    _check_finite_ss(ys, model, "simulation")
    if y is None:
        return ys
    with np.errstate(over="ignore", invalid="ignore"):
        basis = free_response_rows(model.A, model.C, u.size)
    _check_finite_ss(basis, model, "free response")
    norms = np.sqrt(np.einsum("ij,ij->j", basis, basis))
    norms[norms == 0] = 1.0
    x0, *_ = np.linalg.lstsq(basis / norms, y - ys, rcond=None)
    return ys + (basis / norms) @ x0


def predict(model, data: IDData, k=1) -> np.ndarray:
    """k-step-ahead prediction ``y_hat(t | t-k)``; ``k = inf`` is simulation.

    Uses ``y_hat = W_k G u + (1 - W_k) y`` with ``W_k = Hbar_k H^-1`` and
    ``Hbar_k`` the first ``k`` impulse-response terms of ``H = C/(A D)``
    (Ljung 1999, eq. 3.31), zero initial conditions; an IDSS through its
    Kalman predictor ``A - K C`` and ``k - 1`` free steps of ``A``
    (:func:`sysid.state_response.predict_states`), the same predictor.

    Parameters
    ----------
    model : IDPoly, IDSS or IDTF
    data : IDData
        Measured input and output, shape (N,) each.
    k : int or math.inf
        Prediction horizon in samples, ``>= 1``.  A horizon of ``N`` samples or more
        is the simulation (as ``k = inf``): no measured output lies ``k`` samples
        before any sample of the record, so ``y_hat(t | t-k)`` uses none, and it is
        computed so (the predictor polynomials of such a ``k`` would hold ``k`` terms).

    Returns
    -------
    ndarray, shape (N,)
    """
    data = check_data(data)
    if k is None or (isinstance(k, (int, float, np.integer, np.floating)) and k == math.inf):
        return simulate(model, data)
    try:
        ok = not isinstance(k, (bool, np.bool_)) and float(k).is_integer() and k >= 1
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise SysidError(f"k must be an integer >= 1 or math.inf, got {k!r}.")
    if k >= data.N:
        return simulate(model, data)
    k = int(k)
    if isinstance(model, IDSS):
        _check_sample_time(model.Ts, data.Ts)
        _check_parameters_finite(model)
        with np.errstate(over="ignore", invalid="ignore"):
            yhat = predict_states(model.A, model.B, model.C, model.D, model.K, data.y, data.u, k)
        _check_finite_ss(yhat, model, f"{k}-step prediction")
        return yhat
    m = as_idpoly(model, data.Ts)
    AD = np.convolve(m.A, m.D)
    delta = np.zeros(k)
    delta[0] = 1.0
    hbar = lfilter(m.C, AD, delta)
    num_u = np.convolve(hbar, np.convolve(m.D, m.B))
    den = np.convolve(m.C, m.F)
    hAD = np.convolve(hbar, AD)
    n = max(hAD.size, m.C.size)
    num_y = _pad(m.C, n) - _pad(hAD, n)
    num_y[:k] = 0.0  # exact zeros by construction; remove round-off
    with np.errstate(over="ignore", invalid="ignore"):
        if k <= DIRECT_HORIZON:
            yhat = lfilter(num_u, den, data.u) + lfilter(num_y, m.C, data.y)
        else:  # the same filters: hbar (k terms) by FFT after D B/(C F), num_y's k leading zeros as a shift
            N = data.N
            yhat = fftconvolve(hbar, lfilter(np.convolve(m.D, m.B), den, data.u))[:N]
            yhat[k:] += lfilter(num_y[k:], m.C, data.y)[:N - k]
    _check_finite(yhat, m, f"{k}-step prediction")
    return yhat


def fit_percent(y, yhat) -> float:
    """MATLAB fit: ``100 (1 - ||y - yhat|| / ||y - mean(y)||)`` in percent.

    Undefined for a constant ``y`` (the denominator is zero; MATLAB returns -Inf
    or NaN): refused with :class:`SysidError`.
    """
    y, yhat = as_signal(y, "y"), as_signal(yhat, "yhat")
    if y.size != yhat.size:
        raise SysidError(f"y and yhat must have the same length, got {y.size} and {yhat.size} samples.")
    den = float(np.linalg.norm(y - y.mean()))
    if not den > 0.0:
        raise SysidError(f"y is constant ({y.size} samples equal to {y[0]:.6g}): the fit % "
                         f"100 (1 - |y - yhat| / |y - mean(y)|) is undefined; validate on data that vary.")
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / den))


def compare(data: IDData, model, k=math.inf, initial: str = "estimate") -> float:
    """MATLAB ``compare``: fit in percent of the model output to ``data.y``.

    Parameters
    ----------
    data : IDData
        Validation data.
    model : IDPoly, IDSS or IDTF
    k : int or math.inf
        ``math.inf`` (default): simulation; integer: k-step prediction.
    initial : {"estimate", "zero"}
        Initial conditions of the simulation: estimated by least squares
        (default, MATLAB's ``compare`` default ``'e'``) or zero.  k-step
        predictions start from zero (their transient lasts about k samples).

    Returns
    -------
    float
        Fit in percent (100 is perfect, can be negative).

    Raises
    ------
    SysidError
        When the model's sample time differs from the data's, ``data.y`` is
        constant (fit undefined) or the simulation of an unstable model overflows.
    """
    data = check_data(data)
    if initial not in ("zero", "estimate"):
        raise SysidError(f"initial must be 'zero' or 'estimate', got {initial!r}.")
    if not np.ptp(data.y) > 0:
        raise SysidError(f"data.y is constant ({data.N} samples equal to {data.y[0]:.6g}): the fit % "
                         f"100 (1 - |y - yhat| / |y - mean(y)|) is undefined; validate on data that vary.")
    if k == math.inf:
        yhat = simulate(model, data, initial=initial)
    else:
        yhat = predict(model, data, k)
    return fit_percent(data.y, yhat)
