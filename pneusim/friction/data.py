"""One seal-friction test file: piston moved back and forth at a constant chamber pressure.

The format is the TU Delft 2021 friction data set's (``shared/data/real/
cylinder_seal_friction_tudelft2021/README.md``): a CSV with the header
``time_ms, laser_V, pressure_V, force_V, laser_position_mm, pressure_bar_gauge,
force_N`` (only ``time_ms``, ``laser_position_mm``, ``pressure_bar_gauge`` and
``force_N`` are used; other columns may be absent), one numeric row per
sample.  The file is read as it is; nothing is repaired.

Friction is the authors' definition, ``F_friction = F_rod - p_gauge A``
(N), with ``A`` the bore area; positive friction opposes extension
(positive velocity), as in :mod:`pneusim.model.piston`.  The piston velocity is
the slope of a least-squares line through the positions around each sample
(15 samples, about 0.15 s), within each run (runs are split at time gaps).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputFileError

__all__ = ["FrictionTest", "read_friction_test", "KNOWN_BORES_M", "seal_of"]

#: bores of the TU Delft 2021 cylinders (their README: 25.0 mm, and 25.7 mm for the "257" pistons), m
KNOWN_BORES_M = {"O-ring": 0.025, "O-ring257": 0.0257, "X-ring257": 0.0257, "Circle": 0.025}

REQUIRED = ("time_ms", "laser_position_mm", "pressure_bar_gauge", "force_N")

#: samples dropped at the start of each file (the authors drop the first 15: the rig settles)
SKIP_SAMPLES = 15

#: a time step longer than this many median steps starts a new run
GAP_FACTOR = 3.0

#: samples in the window of the local line whose slope is the velocity (about 0.15 s at 10 ms)
SMOOTHING_SAMPLES = 15


@dataclass
class FrictionTest:
    """A friction test at one chamber pressure.

    Attributes
    ----------
    path : Path
    seal : str
        Which cylinder/seal (the file name without ``_<p>bar``).
    bore_m : float
    time_s, position_m, pressure_gauge_Pa, force_N : ndarray, shape (N,)
        The samples kept (the first :data:`SKIP_SAMPLES` dropped).
    velocity_m_per_s : ndarray, shape (N,)
        Piston velocity (smoothed position differentiated within each run).
    run : ndarray of int, shape (N,)
        Run index of each sample (runs are separated by time gaps).
    """

    path: Path
    seal: str
    bore_m: float
    time_s: np.ndarray
    position_m: np.ndarray
    pressure_gauge_Pa: np.ndarray
    force_N: np.ndarray
    velocity_m_per_s: np.ndarray
    run: np.ndarray

    @property
    def area_m2(self) -> float:
        return math.pi / 4.0 * self.bore_m ** 2

    @property
    def friction_N(self) -> np.ndarray:
        """Measured friction ``F_rod - p_gauge A``, N."""
        return self.force_N - self.pressure_gauge_Pa * self.area_m2

    @property
    def mean_pressure_gauge_Pa(self) -> float:
        return float(np.mean(self.pressure_gauge_Pa))

    @property
    def label(self) -> str:
        return f"{self.seal} {self.mean_pressure_gauge_Pa / 1e5:.1f} bar"


def seal_of(path) -> str:
    """The seal name of a file: its stem without a trailing ``_<number>bar``."""
    stem = Path(path).stem
    match = re.fullmatch(r"(.+)_(\d+(?:\.\d+)?)bar", stem)
    return match.group(1) if match else stem


def read_friction_test(path, bore_m: float | None = None) -> FrictionTest:
    """Read one friction file.

    Parameters
    ----------
    path : str or Path
    bore_m : float, optional
        Bore diameter, m; default from :data:`KNOWN_BORES_M` by the seal name.

    Raises
    ------
    InputFileError
        Missing file or column, a non-numeric or non-finite value, time not
        increasing, too few samples, no motion, or an unknown bore.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError("file not found" if not path.exists() else "not a file", path=path)
    if path.suffix.lower() != ".csv":
        raise InputFileError(f"expected a .csv friction file, got {path.suffix or 'no suffix'!r}", path=path)
    seal = seal_of(path)
    if bore_m is None:
        if seal not in KNOWN_BORES_M:
            raise InputFileError(f"the bore of seal {seal!r} is not known; give it with --bore {seal}=METRES",
                                 path=path)
        bore_m = KNOWN_BORES_M[seal]
    if not (math.isfinite(bore_m) and 0.0 < bore_m < 1.0):
        raise InputFileError(f"bore must be in (0, 1) m, got {bore_m}", path=path)
    try:
        text = path.read_text(encoding="utf-8-sig")    # a byte order mark before the header, as recordings allow
    except UnicodeDecodeError as exc:
        raise InputFileError(f"not UTF-8 text (byte offset {exc.start}); expected a CSV file", path=path) from None
    data = _parse(path, text)
    if data.shape[0] < SKIP_SAMPLES + 10 * SMOOTHING_SAMPLES:
        raise InputFileError(f"{data.shape[0]} samples; a friction test needs at least "
                             f"{SKIP_SAMPLES + 10 * SMOOTHING_SAMPLES}", path=path)
    data = data[SKIP_SAMPLES:]
    time_s, position_m = data[:, 0] * 1e-3, data[:, 1] * 1e-3
    pressure_Pa, force_N = data[:, 2] * 1e5, data[:, 3]
    run = _runs(time_s)
    velocity = _velocity(time_s, position_m, run)
    if np.ptp(position_m) < 1e-3 or np.max(np.abs(velocity)) < 1e-4:
        raise InputFileError("the piston does not move (position range "
                             f"{np.ptp(position_m) * 1e3:.2f} mm); a friction test needs strokes",
                             path=path, field="laser_position_mm")
    return FrictionTest(path, seal, float(bore_m), time_s, position_m, pressure_Pa, force_N, velocity, run)


def _parse(path: Path, text: str) -> np.ndarray:
    """The four used columns, shape (N, 4), in :data:`REQUIRED` order; a clean file takes NumPy's fast
    reader, anything else the line-by-line check that names the first bad line and field."""
    lines = text.splitlines()
    if not lines:
        raise InputFileError("empty file; expected a header line " + ",".join(REQUIRED), path=path, line=1)
    header = [h.strip() for h in lines[0].split(",")]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise InputFileError(f"header lacks column {missing[0]!r}; expected the columns {', '.join(REQUIRED)}",
                             path=path, line=1, field=missing[0])
    columns = [header.index(c) for c in REQUIRED]
    if len(lines) > 1 and all(line.strip() for line in lines[1:]):
        try:
            data = np.loadtxt(lines[1:], delimiter=",", usecols=columns, ndmin=2)
        except ValueError:
            data = None
        if (data is not None and data.shape[1] == len(REQUIRED) and np.all(np.isfinite(data))
                and np.all(np.diff(data[:, 0]) > 0) and all(line.count(",") == len(header) - 1 for line in lines[1:])):
            return data
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) != len(header):
            raise InputFileError(f"{len(cells)} fields, expected {len(header)} as in the header", path=path,
                                 line=number)
        row = []
        for name, col in zip(REQUIRED, columns):
            text = cells[col].strip()
            try:
                value = float(text)
            except ValueError:
                raise InputFileError(f"expected a number, got {text!r}", path=path, line=number,
                                     field=name) from None
            if not math.isfinite(value):
                raise InputFileError(f"expected a finite number, got {text!r}", path=path, line=number, field=name)
            row.append(value)
        if rows and row[0] <= rows[-1][0]:
            raise InputFileError(f"time {row[0]} ms does not increase (previous {rows[-1][0]} ms)", path=path,
                                 line=number, field="time_ms")
        rows.append(row)
    return np.array(rows, float).reshape(-1, len(REQUIRED))


def _runs(time_s: np.ndarray) -> np.ndarray:
    dt = np.diff(time_s)
    gaps = dt > GAP_FACTOR * np.median(dt)
    return np.concatenate([[0], np.cumsum(gaps)]).astype(int)


def _velocity(time_s: np.ndarray, position_m: np.ndarray, run: np.ndarray) -> np.ndarray:
    """Slope of the least-squares line through the :data:`SMOOTHING_SAMPLES` positions around each
    sample, against the recorded (uneven) times, within its run; windows shrink at the ends of a run.
    (At the centre of a symmetric window this is the Savitzky-Golay derivative of a quadratic.)"""
    velocity = np.zeros_like(position_m)
    half = SMOOTHING_SAMPLES // 2
    for r in np.unique(run):
        idx = np.flatnonzero(run == r)
        if idx.size < 2:
            continue
        t = time_s[idx] - time_s[idx].mean()
        x = position_m[idx] - position_m[idx].mean()
        sums = [np.concatenate([[0.0], np.cumsum(q)]) for q in (np.ones_like(t), t, x, t * t, t * x)]
        i = np.arange(t.size)
        lo, hi = np.maximum(i - half, 0), np.minimum(i + half + 1, t.size)
        n, st, sx, stt, stx = (c[hi] - c[lo] for c in sums)
        velocity[idx] = (n * stx - st * sx) / (n * stt - st * st)
    return velocity
