"""Input-output data container in the spirit of MATLAB's ``iddata``.

Only single-input single-output records are supported.  Signals are stored as
1-D float arrays of equal length ``N``; the sample time ``Ts`` is in seconds.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import SysidError

__all__ = ["IDData", "iddata", "detrend"]


def real_number(value, name: str, expected: str) -> float:
    """``value`` as a float when it is one real number, else :class:`SysidError` ``"{name} must be {expected}"``.

    Accepted: Python and NumPy integers and floats, 0-d real arrays.  Refused: ``bool``
    (``True`` is not a sample time or a forgetting factor), text, complex numbers, sequences.
    """
    ok = isinstance(value, numbers.Real) or (isinstance(value, np.ndarray) and value.ndim == 0
                                             and value.dtype.kind in "iuf")
    if not ok or isinstance(value, (bool, np.bool_)):
        raise SysidError(f"{name} must be {expected}, got {value!r} ({type(value).__name__}).")
    return float(value)


def check_sample_time(value, name: str = "Ts") -> float:
    """A sample time in seconds: one real, finite number > 0 (as a float)."""
    ts = real_number(value, name, "a positive number of seconds")
    if not (math.isfinite(ts) and ts > 0):
        raise SysidError(f"{name} must be a positive number of seconds, got {value!r}.")
    return ts


def as_signal(x, name: str) -> np.ndarray:
    """``x`` as a finite, real 1-D float array (a column or row vector is flattened).

    A complex array is accepted only when every imaginary part is zero (nothing is
    dropped); text is refused rather than parsed.
    """
    try:
        a = np.asarray(x)
    except (TypeError, ValueError):
        raise SysidError(f"{name} must be a numeric 1-D array, got {type(x).__name__}.") from None
    if a.dtype.kind == "c":
        bad = np.flatnonzero(np.ravel(a.imag) != 0)
        if bad.size:
            i = int(bad[0])
            raise SysidError(f"{name} must be real, but sample {i} is {np.ravel(a)[i]} (complex); pass its real "
                             f"part or its magnitude explicitly.")
        a = a.real
    if a.dtype.kind in "US":
        raise SysidError(f"{name} must be a numeric 1-D array, got text ({type(x).__name__}).")
    try:
        a = a.astype(float)
    except (TypeError, ValueError):
        raise SysidError(f"{name} must be a numeric 1-D array, got {type(x).__name__}.") from None
    if a.ndim == 2 and 1 in a.shape:
        a = a.reshape(-1)
    if a.ndim != 1:
        raise SysidError(f"{name} must be a 1-D array (single channel), got shape {a.shape}.")
    if not np.all(np.isfinite(a)):
        i = int(np.flatnonzero(~np.isfinite(a))[0])
        raise SysidError(f"{name} must be finite, but sample {i} is {a[i]}.")
    return a


@dataclass(frozen=True)
class IDData:
    """Sampled single-input single-output data.

    Parameters
    ----------
    y : ndarray, shape (N,)
        Output samples, in ``output_unit``.
    u : ndarray, shape (N,)
        Input samples, in ``input_unit`` (held constant between samples).
    Ts : float
        Sample time in seconds, > 0.
    output_name, input_name, output_unit, input_unit : str
        Signal names and units (metadata only).
    tstart : float
        Time of the first sample in seconds.
    """

    y: np.ndarray
    u: np.ndarray
    Ts: float
    output_name: str = "y"
    input_name: str = "u"
    output_unit: str = ""
    input_unit: str = ""
    tstart: float = 0.0
    metadata: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        y = as_signal(self.y, "y")
        u = as_signal(self.u, "u")
        if y.shape != u.shape:
            raise SysidError(
                f"y and u must have the same length, got {y.size} output and {u.size} input samples.")
        ts = check_sample_time(self.Ts)
        t0 = real_number(self.tstart, "tstart", "a finite number of seconds")
        if not math.isfinite(t0):
            raise SysidError(f"tstart must be a finite number of seconds, got {self.tstart!r}.")
        if y.size < 2:
            raise SysidError(f"y and u must hold at least 2 samples, got {y.size}.")
        y.setflags(write=False)
        u.setflags(write=False)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "Ts", ts)
        object.__setattr__(self, "tstart", t0)

    def __len__(self) -> int:
        return self.y.size

    @property
    def N(self) -> int:
        """Number of samples."""
        return self.y.size

    @property
    def time(self) -> np.ndarray:
        """Sample instants in seconds, shape (N,)."""
        return self.tstart + self.Ts * np.arange(self.N)

    def __getitem__(self, index) -> "IDData":
        """Slice samples, e.g. ``data[:300]`` (estimation) and ``data[300:]`` (validation)."""
        if not isinstance(index, slice):
            raise SysidError("IDData index must be a slice of samples such as data[:300].")
        start, stop, step = index.indices(self.N)
        if step != 1:
            return replace(self, y=self.y[index], u=self.u[index], Ts=self.Ts * step,
                           tstart=self.tstart + start * self.Ts)
        return replace(self, y=self.y[index], u=self.u[index], tstart=self.tstart + start * self.Ts)

    def split(self, n_estimation: int) -> tuple["IDData", "IDData"]:
        """Split into an estimation part (first ``n_estimation`` samples) and a validation part."""
        if not (2 <= int(n_estimation) <= self.N - 2):
            raise SysidError(f"n_estimation must be between 2 and N-2 = {self.N - 2}, got {n_estimation}.")
        n = int(n_estimation)
        return self[:n], self[n:]

    def detrend(self, order: int = 0) -> "IDData":
        """Return a copy with the mean (``order=0``) or linear trend (``order=1``) removed."""
        return detrend(self, order)


def iddata(y, u, Ts, **kwargs) -> IDData:
    """Create an :class:`IDData` like MATLAB's ``iddata(y, u, Ts)``.

    Parameters
    ----------
    y : array_like, shape (N,)
        Output samples.
    u : array_like, shape (N,)
        Input samples.
    Ts : float
        Sample time in seconds.
    **kwargs
        ``output_name``, ``input_name``, ``output_unit``, ``input_unit``, ``tstart``.
    """
    return IDData(y, u, Ts, **kwargs)


def detrend(data: IDData, order: int = 0) -> IDData:
    """Remove the mean (``order=0``) or a straight line (``order=1``) from y and u.

    Parameters
    ----------
    data : IDData
    order : {0, 1}

    Returns
    -------
    IDData
        Detrended copy; the removed offsets are not stored.
    """
    if isinstance(order, (bool, np.bool_)) or order not in (0, 1):
        raise SysidError(f"order must be 0 (mean) or 1 (linear trend), got {order!r}.")
    from scipy.signal import detrend as _dt
    kind = "constant" if order == 0 else "linear"
    return replace(data, y=_dt(data.y, type=kind), u=_dt(data.u, type=kind))
