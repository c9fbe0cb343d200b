"""Recordings: read, check, write and summarize ``pneusim-recording/1`` data.

A recording is what a rig's data acquisition writes (or what a simulated run
saves): sampled valve command, piston position and, where the rig has the
sensors, chamber pressures.  The contract is ``shared/spec/recording-format.md``;
this module implements it exactly.  Two forms share one :class:`Recording`:

* CSV: ``# key: value`` metadata lines, one header row, numeric rows;
* MATLAB ``.mat``: the column names as column vectors, ``sample_time_s`` as a
  scalar, the other metadata as char arrays.

Every departure from the contract is refused with an
:class:`~pneusim.errors.InputFileError` naming the file, the line (CSV, 1-based,
metadata lines counted) or the variable (``.mat``), the column, and what was
expected.  Nothing is repaired and nothing is half-loaded.  In optional and
extra columns an empty cell or ``nan`` is a gap: it is kept as NaN, never
interpolated (see :meth:`Recording.gap_mask`).

The checks of the contract, and the place a fault is named by, are
:mod:`pneusim.recording_checks`; this module holds the recording, its two file
forms and its summary.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np

from .errors import InputFileError
from .outputs import atomic_path, write_text_atomic
# the format's constants are offered here too, where readers of recordings look for them
from .recording_checks import (CONTROLLER_KEYS, FORMAT, MIN_SAMPLES, OPTIONAL_COLUMNS,  # noqa: F401
                               POSITION_MARGIN, PRESSURE_COLUMNS, PRESSURE_MAX_PA, REQUIRED_COLUMNS, SIGNALS,
                               TIME_RTOL, Place, as_vector, check_columns, check_metadata, rules)

__all__ = ["Recording", "read_recording", "write_recording", "summarize", "FORMAT",
           "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "PRESSURE_COLUMNS", "MIN_SAMPLES"]


_KEY = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
_META = re.compile(r"#\s*([A-Za-z][A-Za-z0-9_]*)\s*:(.*)\Z")


@dataclasses.dataclass(eq=False)
class Recording:
    """One sampled experiment (measured on a rig or simulated).

    Attributes
    ----------
    time_s, valve_cmd_V, position_m:
        Required signals, float arrays of shape (N,): sample instants [s], valve
        command [V] and piston position from the retracted end [m].
    reference_m:
        Position reference of a closed loop [m], shape (N,), or ``None``.
    pressure_a_Pa, pressure_b_Pa, supply_Pa:
        Absolute cap-end, rod-end and supply pressures [Pa], shape (N,), or ``None``.
        NaN marks a gap (a sample the sensor did not deliver).
    metadata:
        Every ``key: value`` pair, values as text; ``format`` and
        ``sample_time_s`` are always present (``format`` is filled in when
        missing from a recording built in code).
    extra:
        Other columns, ``{name: float array (N,)}``, kept and carried along.
    source:
        File the recording was read from, or ``None``.

    Raises
    ------
    InputFileError
        On construction, for the same faults :func:`read_recording` refuses,
        except the minimum length and the stroke range (both file-level checks).
    """

    time_s: np.ndarray
    valve_cmd_V: np.ndarray
    position_m: np.ndarray
    reference_m: np.ndarray | None = None
    pressure_a_Pa: np.ndarray | None = None
    pressure_b_Pa: np.ndarray | None = None
    supply_Pa: np.ndarray | None = None
    metadata: dict[str, str] = dataclasses.field(default_factory=dict)
    extra: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    source: str | None = None
    #: CSV line of sample 0 when read from a CSV file (to name lines in messages), else ``None``
    first_row_line: int | None = dataclasses.field(default=None, repr=False)

    def __post_init__(self):
        place = Place()
        meta = {"format": FORMAT} if "format" not in self.metadata else {}
        for key, value in self.metadata.items():
            if not isinstance(key, str) or not _KEY.match(key):
                place.fail("metadata keys must be names (letters, digits, _)", str(key))
            value = value if isinstance(value, str) else str(value)
            if "\n" in value or "\r" in value:
                place.fail("metadata values must be a single line", key)
            meta[key] = value.strip()
        self.metadata = meta
        for name in SIGNALS:
            if getattr(self, name) is not None:
                setattr(self, name, as_vector(getattr(self, name), name, place))
        self.extra = {str(k): as_vector(v, str(k), place) for k, v in self.extra.items()}
        for name in self.extra:
            if name in SIGNALS:
                place.fail("extra column has the name of a signal; pass it as that signal", name)
        check_metadata(self.metadata, place)
        check_columns(self.columns(), self.metadata, place, stroke_m=None, min_samples=0)

    # ----------------------------------------------------------------- access
    @property
    def sample_time_s(self) -> float:
        """Nominal sample time [s], from the metadata."""
        return float(self.metadata["sample_time_s"])

    @property
    def rig(self) -> str | None:
        """Nominal rig id (``paper1-mre``, ``paper2-enfield``, a user's rig), or ``None``."""
        return self.metadata.get("rig") or None

    @property
    def loop(self) -> str | None:
        """``'open'``, ``'closed'`` or ``None`` when the metadata does not say."""
        return self.metadata.get("loop") or None

    @property
    def controller(self) -> dict[str, float] | None:
        """Constants of the proportional controller, or ``None``.

        ``u = clip(u0_V + kp_V_per_m * (reference_m - position_m), u_min_V, u_max_V)``
        at each sample, held until the next.  Keys: ``kp_V_per_m`` [V/m],
        ``u0_V``, ``u_min_V``, ``u_max_V`` [V].
        """
        if self.metadata.get("controller") != "proportional":
            return None
        return {key: float(self.metadata[key]) for key in CONTROLLER_KEYS}

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.time_s.shape[0])

    def __len__(self) -> int:
        return self.n_samples

    @property
    def has_pressures(self) -> bool:
        """True when both chamber pressures (A and B) were recorded."""
        return self.pressure_a_Pa is not None and self.pressure_b_Pa is not None

    def columns(self) -> dict[str, np.ndarray]:
        """Present columns, ``{name: array (N,)}``: signals in spec order, then extras."""
        cols = {name: getattr(self, name) for name in SIGNALS if getattr(self, name) is not None}
        cols.update(self.extra)
        return cols

    def gap_mask(self, name: str) -> np.ndarray:
        """Boolean array (N,), True where column ``name`` has a gap (NaN)."""
        return np.isnan(self.columns()[name])

    def slice(self, t_start_s: float | None = None, t_end_s: float | None = None) -> "Recording":
        """Samples with ``t_start_s <= time_s < t_end_s`` [s] as a new Recording.

        ``None`` leaves that end open.  Time is not shifted.  The result may hold
        fewer than :data:`MIN_SAMPLES` samples (that minimum applies to files).
        """
        keep = np.ones(self.n_samples, dtype=bool)
        if t_start_s is not None:
            keep &= self.time_s >= t_start_s
        if t_end_s is not None:
            keep &= self.time_s < t_end_s
        if not keep.any():
            raise InputFileError(f"no sample in [{t_start_s}, {t_end_s}) s", path=self.source, field="time_s")
        signals = {n: (None if getattr(self, n) is None else getattr(self, n)[keep].copy()) for n in SIGNALS}
        return Recording(**signals, metadata=dict(self.metadata),
                         extra={k: v[keep].copy() for k, v in self.extra.items()}, source=self.source)


# ------------------------------------------------------------------ reading
def read_recording(path: str | Path, stroke_m: float | None = None) -> Recording:
    """Read and check a ``pneusim-recording/1`` file (``.csv`` or ``.mat``).

    Parameters
    ----------
    path:
        The file; its suffix chooses the form.
    stroke_m:
        Stroke [m] for the position range check (position within
        [-1 %, 101 %] of it).  ``None``: the stroke of the rig named in the
        metadata when it is a shipped rig, else no range check.

    Returns
    -------
    Recording

    Raises
    ------
    InputFileError
        For every fault listed in the spec's "Bad input" section and any other
        departure from the format, naming file, line or variable, and column.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".mat"):
        raise InputFileError(f"unknown file type {path.suffix or '(none)'!r}; expected a .csv or .mat recording",
                             path=path)
    if not path.is_file():
        raise InputFileError("file not found" if not path.exists() else "not a file", path=path)
    meta, cols, place = (_parse_csv if suffix == ".csv" else _parse_mat)(path)
    check_metadata(meta, place)
    if stroke_m is None and meta.get("rig"):
        stroke_m = rules.stroke_of(meta["rig"])
    check_columns(cols, meta, place, stroke_m=stroke_m)
    signals = {name: cols.pop(name) for name in SIGNALS if name in cols}
    return Recording(**signals, metadata=meta, extra=cols, source=str(path), first_row_line=place.first_row_line)


def _parse_csv(path: Path):
    data = path.read_bytes()
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"not UTF-8 text (byte 0x{data[exc.start]:02x}); expected a UTF-8 CSV file",
                             path=path, line=data.count(b"\n", 0, exc.start) + 1) from None
    lines = [line.rstrip("\r") for line in text.split("\n")]
    while lines and not lines[-1].strip():
        lines.pop()
    meta: dict[str, str] = {}
    key_lines: dict[str, int] = {}
    h = 0
    while h < len(lines) and lines[h].startswith("#"):
        match = _META.match(lines[h])
        if not match:
            raise InputFileError(f"metadata line {lines[h]!r} is not of the form '# key: value'",
                                 path=path, line=h + 1)
        key, value = match.group(1), match.group(2).strip()
        if key in meta:
            raise InputFileError(f"metadata key repeated (first on line {key_lines[key]})",
                                 path=path, line=h + 1, field=key)
        meta[key], key_lines[key] = value, h + 1
        h += 1
    if h == len(lines):
        raise InputFileError("no header row; expected a line of column names after the metadata",
                             path=path, line=h + 1)
    names = [name.strip() for name in lines[h].split(",")]
    place = Place(path, key_lines, h + 1, h + 2)
    for i, name in enumerate(names):
        if not name:
            place.fail(f"column {i + 1} of the header has no name", f"column {i + 1}", header=True)
        if name in names[:i]:
            place.fail("duplicated column name; expected each column once", name, header=True)
    rows = [line.split(",") for line in lines[h + 1:]]
    for r, cells in enumerate(rows):
        if len(cells) != len(names):
            field = names[len(cells)] if len(cells) < len(names) else None
            place.fail(f"row has {len(cells)} cells; expected {len(names)} ({', '.join(names)})", field, row=r)
    required = set(REQUIRED_COLUMNS) | ({"reference_m"} if meta.get("loop") == "closed" else set())
    cols = {}
    for c, name in enumerate(names):
        cells = [cells[c] for cells in rows]
        try:
            if any("_" in cell for cell in cells):  # float() accepts '1_000'; the format does not
                raise ValueError
            cols[name] = np.array(cells, dtype=float)
        except ValueError:
            cols[name] = _parse_cells(cells, name, name in required, place)
    return meta, cols, place


def _parse_cells(cells: list[str], name: str, required: bool, place: Place) -> np.ndarray:
    values = np.empty(len(cells))
    for r, cell in enumerate(cells):
        if not cell.strip():
            if required:
                place.fail("empty cell in a required column; expected a number", name, row=r)
            values[r] = math.nan
        elif rules.NUMBER.match(cell):
            values[r] = float(cell)
        else:
            place.fail(f"{cell.strip()!r} is not a number; expected a decimal number with '.'", name, row=r)
    return values


#: metadata a .mat file holds as numbers (one value each), not as columns
_NUMERIC_META = ("sample_time_s", "seed", "noise_scale") + CONTROLLER_KEYS


def _parse_mat(path: Path):
    import scipy.io

    try:
        raw = scipy.io.loadmat(path, chars_as_strings=True)
    except NotImplementedError:
        raise InputFileError("MATLAB v7.3 (HDF5) files are not supported; save with -v7", path=path) from None
    except Exception as exc:  # scipy raises several types for a damaged file
        raise InputFileError(f"not a readable MATLAB .mat file ({exc})", path=path) from None
    place = Place(path)
    meta: dict[str, str] = {}
    cols: dict[str, np.ndarray] = {}
    for name, value in raw.items():
        if name.startswith("__"):
            continue
        value = np.asarray(value)
        shape = "x".join(map(str, value.shape))
        if value.dtype.kind == "U" and name not in SIGNALS:
            if value.size > 1:
                place.fail("expected a one-line char array", name)
            meta[name] = str(value.reshape(-1)[0]) if value.size else ""
        elif value.dtype.kind in "biuf" and not value.size:
            place.fail(f"is empty (a {shape} array); expected "
                       + ("a column vector of the samples" if name in SIGNALS or name not in _NUMERIC_META
                          else "a single number"), name)
        elif value.dtype.kind in "biuf":
            if value.ndim > 2 or (value.ndim == 2 and 1 not in value.shape):
                place.fail(f"expected a column vector, got a {shape} array", name)
            flat = value.reshape(-1).astype(float)
            if name in _NUMERIC_META and flat.size != 1:
                place.fail(f"expected a single number (a 1x1 value), got a {shape} array", name)
            if name in SIGNALS or flat.size != 1:
                cols[name] = flat
            elif not math.isfinite(flat[0]):
                place.fail(f"expected a finite number, got {flat[0]!r}", name)
            else:
                meta[name] = repr(float(flat[0]))
        else:
            place.fail(f"expected a numeric column vector or a char array, got MATLAB type {value.dtype}", name)
    return meta, cols, place


# ------------------------------------------------------------------ writing
def write_recording(recording: Recording, path: str | Path, significant_digits: int | None = None) -> None:
    """Write a recording as ``.csv`` or ``.mat`` (chosen by the suffix of ``path``).

    Parameters
    ----------
    recording:
        What to write.
    path:
        Target file; replaced atomically (a temporary file in the same folder, then renamed: a failed
        write leaves the previous file whole).
    significant_digits:
        CSV only: digits of every column but ``time_s`` (``None``: full
        precision, an exact round trip).  ``time_s`` is always written in full.
        Gaps (NaN) are written as empty cells.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    cols = recording.columns()
    if suffix == ".csv":
        lines = [f"# {key}: {value}" for key, value in recording.metadata.items()]
        lines.append(",".join(cols))
        fmt = repr if significant_digits is None else (lambda v: f"{v:.{int(significant_digits)}g}")
        text_cols = [[("" if v != v else (repr(v) if name == "time_s" else fmt(v))) for v in values.tolist()]
                     for name, values in cols.items()]
        lines.extend(",".join(row) for row in zip(*text_cols))
        write_text_atomic(path, "\n".join(lines) + "\n")
    elif suffix == ".mat":
        import scipy.io

        for name in cols:
            if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,62}", name):
                raise InputFileError("column name is not a valid MATLAB variable name", path=path, field=name)
        out: dict[str, object] = {k: v for k, v in recording.metadata.items() if k != "sample_time_s"}
        out["sample_time_s"] = recording.sample_time_s
        out.update({name: values.reshape(-1, 1) for name, values in cols.items()})
        with atomic_path(path) as tmp:
            scipy.io.savemat(tmp, out, oned_as="column")
    else:
        raise InputFileError(f"unknown file type {path.suffix or '(none)'!r}; expected .csv or .mat", path=path)


# ------------------------------------------------------------------ summary
def summarize(recording: Recording) -> str:
    """A few lines for people (``pneusim check``): size, timing, rig, loop, columns and gaps."""
    r = recording
    t = r.time_s
    out = [f"recording: {r.source or '(in memory)'}",
           f"samples: {r.n_samples}, duration {t[-1] - t[0]:.6g} s ({t[0]:.6g} .. {t[-1]:.6g} s), "
           f"sample time {r.sample_time_s:.6g} s",
           f"rig: {r.rig or '(not given)'}, loop: {r.loop or '(not given)'}"]
    if r.controller:
        out.append("controller: proportional, " + ", ".join(f"{k}={v:g}" for k, v in r.controller.items()))
    out.append(f"pressures: {'chamber A and B' if r.has_pressures else 'not recorded'}")
    out.append("columns:")
    for name, values in r.columns().items():
        gaps = int(np.isnan(values).sum())
        line = f"  {name:<16} min {np.nanmin(values):<12.6g} max {np.nanmax(values):<12.6g}" if gaps < len(values) \
            else f"  {name:<16} (all gaps)"
        if gaps:
            line += f" gaps: {gaps} samples ({100.0 * gaps / len(values):.3g} %)"
        out.append(line.rstrip() + (" (extra)" if name in r.extra else ""))
    if r.metadata.get("description"):
        out.append(f"description: {r.metadata['description']}")
    known = {"format", "sample_time_s", "rig", "loop", "controller", "description", *CONTROLLER_KEYS}
    other = {k: v for k, v in r.metadata.items() if k not in known}
    if other:
        out.append("other metadata: " + ", ".join(f"{k}={v}" for k, v in other.items()))
    return "\n".join(out)
