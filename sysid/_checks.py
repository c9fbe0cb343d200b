"""Shared argument checks (internal)."""
from __future__ import annotations

import numbers
from dataclasses import replace

import numpy as np

from .data import IDData, real_number
from .errors import SysidError


def check_data(data, name: str = "data") -> IDData:
    if not isinstance(data, IDData):
        raise SysidError(f"{name} must be an IDData (use sysid.iddata(y, u, Ts)), got {type(data).__name__}.")
    return data


def check_order(value, name: str, minimum: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise SysidError(f"{name} must be an integer >= {minimum}, got {value!r}.")
    return int(value)


def check_orders(orders, names: tuple[str, ...], minima: tuple[int, ...]) -> tuple[int, ...]:
    try:
        seq = list(orders)
    except TypeError:
        raise SysidError(f"orders must be a list [{', '.join(names)}], got {orders!r}.") from None
    if len(seq) != len(names):
        raise SysidError(f"orders must be a list [{', '.join(names)}] of {len(names)} integers, got {orders!r}.")
    return tuple(check_order(v, n, m) for v, n, m in zip(seq, names, minima))


def check_flag(value, name: str) -> bool:
    """``True`` or ``False`` (Python or NumPy); a string such as ``"no"`` is refused rather than read as true."""
    if not isinstance(value, (bool, np.bool_)):
        raise SysidError(f"{name} must be True or False, got {value!r}.")
    return bool(value)


def check_tolerance(value, name: str) -> float:
    """A finite number >= 0."""
    v = real_number(value, name, "a finite number >= 0")
    if not (np.isfinite(v) and v >= 0):
        raise SysidError(f"{name} must be a finite number >= 0, got {value!r}.")
    return v


def check_enough_data(n_samples: int, n_parameters: int, what: str) -> None:
    if n_samples <= n_parameters:
        raise SysidError(
            f"orders are too high for the data: {what} needs more than {n_parameters} usable samples, "
            f"got {max(n_samples, 0)}.")


def rms_scale(x, name: str) -> float:
    """RMS of ``x`` computed without overflow; refuses an all-zero signal (nothing to identify from)."""
    x = np.asarray(x, dtype=float)
    peak = float(np.max(np.abs(x)))
    if not peak > 0.0:
        raise SysidError(f"{name} must not be all zeros: identification needs a measured output and an exciting input.")
    rms = peak * float(np.sqrt(np.mean((x / peak) ** 2)))
    if not 1e-150 < rms < 1e150:
        raise SysidError(f"{name} has an RMS of {rms:.3g}: its squares (variances, losses) fall outside the "
                         f"floating-point range; express {name} in units that bring it within 1e-150 .. 1e150.")
    return rms


def scaled(data: IDData) -> tuple[IDData, float, float]:
    """``data`` with ``y`` and ``u`` divided by their RMS, and the two RMS values ``(sy, su)``.

    Estimators work on signals of order one so that their sums of squares neither
    overflow (data scaled by 1e200) nor underflow; the models are scaled back.
    """
    sy, su = rms_scale(data.y, "y"), rms_scale(data.u, "u")
    return replace(data, y=data.y / sy, u=data.u / su), sy, su


def unscale_poly(model, sy: float, su: float):
    """Scale an :class:`IDPoly` fitted on ``y/sy, u/su`` back to the data's units (in place; returns it)."""
    g = sy / su
    model.B = model.B * g
    model.noise_variance = model.noise_variance * sy ** 2
    model.loss = model.loss * sy ** 2
    if model.covariance is not None:
        w = np.ones(model.n_parameters)
        w[model.na:model.na + model.nb] = g
        model.covariance = model.covariance * np.outer(w, w)
    if "cost" in model.report:
        model.report["cost"] = model.report["cost"] * sy ** 2
    return model
