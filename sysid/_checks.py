"""Shared argument checks (internal)."""
from __future__ import annotations

import numbers

from .data import IDData
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


def check_enough_data(n_samples: int, n_parameters: int, what: str) -> None:
    if n_samples <= n_parameters:
        raise SysidError(
            f"orders are too high for the data: {what} needs more than {n_parameters} usable samples, "
            f"got {n_samples}.")


def check_forgetting(lam) -> float:
    try:
        v = float(lam)
    except (TypeError, ValueError):
        raise SysidError(f"forgetting must be a number in (0, 1], got {lam!r}.") from None
    if not (0.0 < v <= 1.0):
        raise SysidError(f"forgetting must be a number in (0, 1], got {lam!r}.")
    return v
