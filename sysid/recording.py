"""Reading ``pneusim-recording/1`` files (``/work/shared/spec/recording-format.md``) as :class:`IDData`.

Two forms hold the same content: CSV (``# key: value`` metadata lines, one
header row, numeric rows) and MATLAB ``.mat`` (the column names as column
vectors, ``sample_time_s`` as a scalar, the other metadata as char arrays).
A bad file is refused with one sentence naming the file, the line (or
variable) and the column; nothing is repaired or half-loaded.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from . import format_rules as rules
from .data import IDData
from .errors import SysidError

__all__ = ["load_recording"]

FORMAT = rules.FORMAT
MIN_SAMPLES = rules.MIN_SAMPLES


def load_recording(path, output: str = "position_m", input: str = "valve_cmd_V") -> IDData:
    """Load a ``pneusim-recording/1`` CSV or ``.mat`` file as :class:`IDData`.

    Parameters
    ----------
    path : str or Path
        ``*.mat`` is read as MATLAB, anything else as CSV.
    output, input : str
        Column names used as output (default ``position_m``, m) and input
        (default ``valve_cmd_V``, V).

    Returns
    -------
    IDData
        ``Ts`` from ``sample_time_s``; the other metadata (strings) in ``metadata``;
        units from the column-name suffix (``_m`` -> ``m``).
    """
    path = Path(path)
    if not path.is_file():
        raise SysidError(f"{path}: {'file not found' if not path.exists() else 'not a file'}.")
    # every column the format has rules for is read and checked, as pneusim's reader does
    needed = [output, input, "time_s", *rules.REQUIRED_COLUMNS]
    optional = ["reference_m", *rules.PRESSURE_COLUMNS]
    if path.suffix.lower() == ".mat":
        meta, cols, where = _read_mat(path, needed, optional)
    else:
        meta, cols, where = _read_csv(path, needed, optional)
    # the readers have checked 'format' first (_check_format_first)
    if "sample_time_s" not in meta:
        raise SysidError(f"{path}: metadata 'sample_time_s' is required.")
    try:
        ts = float(meta["sample_time_s"])
    except ValueError:
        raise SysidError(f"{path}: metadata 'sample_time_s' must be a number, got {meta['sample_time_s']!r}.") from None
    if not (np.isfinite(ts) and ts > 0):
        raise SysidError(f"{path}: metadata 'sample_time_s' must be a positive number of seconds, got {ts}.")
    problem = rules.check_sample_time(meta.get("sample_time_s"))
    if problem is not None:
        raise SysidError(f"{path}: metadata 'sample_time_s': {problem.message}.")
    if meta.get("loop") == "closed" and "reference_m" not in cols:
        raise SysidError(f"{path}: required column 'reference_m' is missing (required by 'loop: closed').")
    required = set(rules.REQUIRED_COLUMNS) | ({"reference_m"} if meta.get("loop") == "closed" else set())
    problem = rules.check_values(cols, required, rules.stroke_of(meta.get("rig")))
    if problem is not None:
        at = f":{where(problem.row)}" if problem.row is not None else ""
        raise SysidError(f"{path}{at}: column {problem.column!r}: {problem.message}.")
    n = cols["time_s"].size
    if n < MIN_SAMPLES:
        raise SysidError(f"{path}: a recording must hold at least {MIN_SAMPLES} samples, got {n}.")
    t = cols["time_s"]
    problem = rules.check_time(t, ts)
    if problem is not None:
        at = f":{where(problem.row)}" if problem.row is not None else ""
        raise SysidError(f"{path}{at}: column 'time_s': {problem.message}.")
    ounit = output.rsplit("_", 1)[-1] if "_" in output else ""
    iunit = input.rsplit("_", 1)[-1] if "_" in input else ""
    return IDData(cols[output], cols[input], ts, output_name=output, input_name=input,
                  output_unit=ounit, input_unit=iunit, tstart=float(t[0]), metadata=meta)


def _read_csv(path: Path, needed: list[str], optional: list[str] = ()):
    """Metadata dict, needed columns (float arrays) and ``where(i)`` -> line number of sample ``i``."""
    meta: dict[str, str] = {}
    rows: list[tuple[int, list[str]]] = []
    header = None
    try:
        fh = path.open(newline="", encoding="utf-8")
    except OSError as exc:
        raise SysidError(f"{path}: cannot be opened ({exc.strerror}).") from None
    with fh:
        try:
            lines = list(fh)
        except UnicodeDecodeError as exc:
            raise SysidError(f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x}); expected a UTF-8 CSV "
                             "recording.") from None
        for lineno, line in enumerate(lines, start=1):
            s = line.strip()
            if not s:
                continue
            if header is None and s.startswith("#"):
                key, sep, value = s[1:].partition(":")
                if not sep:
                    raise SysidError(f"{path}:{lineno}: metadata line must read '# key: value'.")
                meta[key.strip().lower()] = value.strip()
                continue
            cells = next(csv.reader([s]))
            if header is None:
                header = [c.strip() for c in cells]
                if len(set(header)) != len(header):
                    dup = next(c for c in header if header.count(c) > 1)
                    raise SysidError(f"{path}:{lineno}: header has the column name {dup!r} twice.")
            else:
                rows.append((lineno, cells))
    if header is None:
        raise SysidError(f"{path}: no header row found.")
    _check_format_first(path, meta)
    cols = {}
    for name in dict.fromkeys(needed + [c for c in optional if c in header]):
        if name not in header:
            raise SysidError(f"{path}: required column {name!r} is missing.")
        is_needed = name in needed
        j = header.index(name)
        vals = np.empty(len(rows))
        for k, (lineno, cells) in enumerate(rows):
            cell = cells[j] if j < len(cells) else None
            if cell is not None and not cell.strip() and not is_needed:
                vals[k] = np.nan   # a gap in an optional column, as pneusim reads it
                continue
            if cell is None or not rules.is_number(cell):
                raise SysidError(f"{path}:{lineno}: column {name!r} must hold a number.")
            vals[k] = float(cell)
            if is_needed and not np.isfinite(vals[k]):
                raise SysidError(f"{path}:{lineno}: column {name!r} must be finite, got {vals[k]}.")
        cols[name] = vals
    return meta, cols, (lambda i: rows[i][0])


def _read_mat(path: Path, needed: list[str], optional: list[str] = ()):
    from scipy.io import loadmat
    try:
        raw = loadmat(str(path), squeeze_me=True, chars_as_strings=True)
    except NotImplementedError:
        raise SysidError(f"{path}: MATLAB v7.3 (HDF5) files are not supported; save with save(..., '-v7').") from None
    except Exception as exc:  # scipy raises several types for a damaged file
        raise SysidError(f"{path}: not a readable MATLAB .mat file ({exc}).") from None
    meta: dict[str, str] = {}
    for key, value in raw.items():
        if key.startswith("__"):
            continue
        if isinstance(value, str):
            meta[key.lower()] = value.strip()
        elif key == "sample_time_s":
            meta[key] = str(np.asarray(value, dtype=float).item()) if np.size(value) == 1 else repr(value)
    _check_format_first(path, meta)
    cols = {}
    for name in dict.fromkeys(needed + [c for c in optional if c in raw]):
        if name not in raw:
            raise SysidError(f"{path}: required variable {name!r} is missing.")
        try:
            v = np.asarray(raw[name], dtype=float)
        except (TypeError, ValueError):
            raise SysidError(f"{path}: variable {name!r} must be a numeric column vector.") from None
        if v.ndim > 1 and v.size != max(v.shape):
            raise SysidError(f"{path}: variable {name!r} must be a column vector, got size {v.shape}.")
        v = v.reshape(-1)
        if name not in needed:
            cols[name] = v   # optional: NaN is a gap; the shared rules refuse infinity
            continue
        if not np.all(np.isfinite(v)):
            i = int(np.flatnonzero(~np.isfinite(v))[0])
            raise SysidError(f"{path}: variable {name!r} must be finite, but element {i + 1} is {v[i]}.")
        cols[name] = v
    sizes = {k: v.size for k, v in cols.items()}
    if len(set(sizes.values())) > 1:
        raise SysidError(f"{path}: variables must have the same length, got {sizes}.")
    return meta, cols, (lambda i: f"time_s({i + 1})")


def _check_format_first(path, meta):
    """The format key decides how the rest is read: check it before the columns."""
    if "format" not in meta:
        raise SysidError(f"{path}: metadata 'format' is required (expected '{FORMAT}').")
    if meta["format"] != FORMAT:
        raise SysidError(f"{path}: metadata 'format' must be '{FORMAT}', got {meta['format']!r}.")
