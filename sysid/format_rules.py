"""The value rules of the ``pneusim-recording/1`` format, shared by its two readers.

``pneusim.recording.read_recording`` and ``sysid.load_recording`` read the same
files; whatever one refuses the other must refuse too.  The rules on values
(numbers, finiteness, time base, pressure and position ranges) live here once.
This module depends on NumPy only: ``sysid`` stays independent of ``pneusim``,
and ``pneusim`` imports it from here.

Every check returns ``None`` when the data pass, else a :class:`Problem` (the
column, the 0-based sample or ``None``, the metadata key or ``None``, and the
message); each reader turns it into its own error naming the file and line.
"""
from __future__ import annotations

import math
import re
from typing import Mapping, NamedTuple

import numpy as np

__all__ = ["FORMAT", "MIN_SAMPLES", "TIME_RTOL", "POSITION_MARGIN", "PRESSURE_MAX_PA", "PRESSURE_COLUMNS",
           "REQUIRED_COLUMNS", "SHIPPED_STROKES_M", "NUMBER", "Problem", "is_number", "stroke_of",
           "check_sample_time", "check_values", "check_time"]

FORMAT = "pneusim-recording/1"
REQUIRED_COLUMNS = ("time_s", "valve_cmd_V", "position_m")
PRESSURE_COLUMNS = ("pressure_a_Pa", "pressure_b_Pa", "supply_Pa")
MIN_SAMPLES = 50
TIME_RTOL = 1e-6              #: spacing tolerance, relative to ``sample_time_s``
POSITION_MARGIN = 0.01        #: position allowed in [-1 %, 101 %] of the stroke
PRESSURE_MAX_PA = 2.0e6

#: strokes [m] of the rigs that ship with pneusim (``pneusim/rigs/*.toml``; a test keeps them equal):
#: a recording that names one of them gets its positions checked against the stroke
SHIPPED_STROKES_M = {"paper1-mre": 0.1, "paper2-enfield": 0.3048,
                     "paper1-mre-realistic": 0.1, "paper2-enfield-realistic": 0.3048}

#: a decimal number as the format writes it ('.' as decimal point, no '_' separators), or nan/inf
NUMBER = re.compile(r"\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*\Z|\s*[+-]?(nan|inf|infinity)\s*\Z", re.I)


class Problem(NamedTuple):
    """A broken rule: ``column`` (or metadata key), 0-based ``row`` or ``None``, ``key`` (a metadata
    key the problem is about, or ``None``) and the ``message``."""

    column: str
    row: int | None
    message: str
    key: str | None = None


def is_number(text: str) -> bool:
    """True when ``text`` is a number the format allows (NaN and infinity included: finiteness is a rule)."""
    return bool(NUMBER.match(text))


def stroke_of(rig_name: str | None) -> float | None:
    """Stroke [m] of a shipped rig, or ``None``."""
    return SHIPPED_STROKES_M.get(rig_name or "")


def check_sample_time(text: str | None) -> Problem | None:
    """``sample_time_s`` metadata: present, a finite number, positive."""
    if text is None:
        return Problem("sample_time_s", None, "missing metadata 'sample_time_s'; expected the sample time in "
                                              "seconds, e.g. '# sample_time_s: 0.01'")
    value = float(text) if is_number(text) else math.nan
    if not math.isfinite(value):
        return Problem("sample_time_s", None, f"expected a finite number, got {text!r}", "sample_time_s")
    if not value > 0:
        return Problem("sample_time_s", None, f"sample time must be positive, got {text!r}", "sample_time_s")
    return None


def check_values(cols: Mapping[str, np.ndarray], required, stroke_m: float | None) -> Problem | None:
    """Values of the columns: finite in required columns (NaN is a gap elsewhere, infinity never),
    pressures in [0, 2 MPa], positions in [-1 %, 101 %] of ``stroke_m`` when it is known."""
    for name, values in cols.items():
        bad = np.flatnonzero(~np.isfinite(values) if name in required else np.isinf(values))
        if bad.size:
            what = "NaN" if np.isnan(values[bad[0]]) else "infinity"
            return Problem(name, int(bad[0]), f"{what} in a required column; expected a finite number"
                           if name in required else f"{what}; expected a finite number or an empty cell (gap)")
    for name in PRESSURE_COLUMNS:
        if name in cols:
            with np.errstate(invalid="ignore"):
                bad = np.flatnonzero((cols[name] < 0) | (cols[name] > PRESSURE_MAX_PA))
            if bad.size:
                return Problem(name, int(bad[0]), f"pressure {float(cols[name][bad[0]])!r} Pa is outside [0 Pa, 2 MPa]; "
                               "expected absolute pressure in Pa (gauge pressure, or bar/kPa written as Pa?)")
    if stroke_m is not None and "position_m" in cols:
        pos = cols["position_m"]
        lo, hi = -POSITION_MARGIN * stroke_m, (1 + POSITION_MARGIN) * stroke_m
        bad = np.flatnonzero((pos < lo) | (pos > hi))
        if bad.size:
            return Problem("position_m", int(bad[0]),
                           f"position {float(pos[bad[0]])!r} m is outside [-1 %, 101 %] of the stroke {stroke_m!r} m "
                           f"([{lo:.6g}, {hi:.6g}] m); it looks like millimetres or volts written as metres")
    return None


def check_time(t: np.ndarray, dt: float) -> Problem | None:
    """``time_s``: strictly increasing, uniform at ``dt`` within :data:`TIME_RTOL` relative."""
    if t.shape[0] < 2:
        return None
    step = np.diff(t)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        return Problem("time_s", i, f"time {float(t[i])!r} s is not after the previous sample {float(t[i - 1])!r} s; "
                                    "expected strictly increasing time")
    tol = TIME_RTOL * dt
    median = float(np.median(step))
    if abs(median - dt) > tol:
        return Problem("sample_time_s", None, f"the time_s spacing is {median!r} s but sample_time_s is {dt!r} s; "
                       f"expected them to agree within {TIME_RTOL:g} relative", "sample_time_s")
    bad = np.flatnonzero(np.abs(step - dt) > tol)
    if bad.size:
        i = int(bad[0]) + 1
        return Problem("time_s", i, f"time step {float(step[i - 1])!r} s from the previous sample; expected uniform "
                                    f"sampling at {dt!r} s within {TIME_RTOL:g} relative")
    return None
