"""The ``pneusim-recording/1`` contract as checks that name where a fault is.

The value rules of the format (sample time, time base, finite values, pressure and position ranges) live
once in ``sysid/format_rules.py``, shared with sysid's reader; this module loads them, adds the checks of
the metadata (format, loop, controller constants) and of the columns (required, lengths, minimum
length), and raises each broken rule as one :class:`~pneusim.errors.InputFileError` naming the file, the
line (CSV) or the variable (``.mat``) and the column, through :class:`Place`.  :mod:`pneusim.recording`
uses it for files and for recordings built in code.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Mapping

import numpy as np

from .errors import InputFileError

__all__ = ["FORMAT", "MIN_SAMPLES", "POSITION_MARGIN", "PRESSURE_COLUMNS", "PRESSURE_MAX_PA", "REQUIRED_COLUMNS",
           "TIME_RTOL", "OPTIONAL_COLUMNS", "SIGNALS", "CONTROLLER_KEYS", "rules", "Place", "as_vector",
           "check_metadata", "check_columns", "finite_number"]


def _load_format_rules():
    """The value rules of the format, which live once in the public module ``sysid/format_rules.py``
    (sysid's reader uses them too and must not import pneusim).  That module depends on NumPy only; it is
    loaded by its file because ``import sysid.format_rules`` would first run ``sysid/__init__.py``, which
    imports every estimator (SciPy's signal and stats: 1.3 s more for ``pneusim check`` than NumPy alone).
    The module is the same object sysid's reader uses once both are loaded (``sys.modules``)."""
    import importlib.util
    import sys

    name = "sysid.format_rules"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec("sysid")
    path = Path(spec.submodule_search_locations[0]) / "format_rules.py"
    module_spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(module_spec)
    sys.modules[name] = module
    module_spec.loader.exec_module(module)
    return module


rules = _load_format_rules()
FORMAT, MIN_SAMPLES, POSITION_MARGIN = rules.FORMAT, rules.MIN_SAMPLES, rules.POSITION_MARGIN
PRESSURE_COLUMNS, PRESSURE_MAX_PA, REQUIRED_COLUMNS, TIME_RTOL = (rules.PRESSURE_COLUMNS, rules.PRESSURE_MAX_PA,
                                                                 rules.REQUIRED_COLUMNS, rules.TIME_RTOL)

#: ``reference_m`` is required too when ``loop: closed``
OPTIONAL_COLUMNS = ("reference_m", "pressure_a_Pa", "pressure_b_Pa", "supply_Pa")
SIGNALS = ("time_s", "reference_m", "valve_cmd_V", "position_m") + PRESSURE_COLUMNS
CONTROLLER_KEYS = ("kp_V_per_m", "u0_V", "u_min_V", "u_max_V")


@dataclasses.dataclass
class Place:
    """Where values came from, to name them in a message: file, metadata lines, rows."""

    path: str | Path | None = None
    key_lines: Mapping[str, int] = dataclasses.field(default_factory=dict)
    header_line: int | None = None
    first_row_line: int | None = None   #: CSV line of sample 0; None: name samples instead

    def problem(self, problem: "rules.Problem | None") -> None:
        """Raise the error of a broken format rule (see :mod:`sysid.format_rules`), if any."""
        if problem is not None:
            if problem.key is not None:
                self.fail(problem.message, problem.column, key=problem.key)
            self.fail(problem.message, problem.column, row=problem.row, header=problem.row is None)

    def fail(self, message: str, field: str | None = None, *, key: str | None = None,
             row: int | None = None, header: bool = False):
        """Raise :class:`~pneusim.errors.InputFileError` at the line of metadata ``key``, of sample ``row``
        (0-based) or of the header."""
        line = None
        if key is not None:
            line = self.key_lines.get(key, self.header_line)
        elif row is not None:
            if self.first_row_line is None:
                message = f"sample {row + 1}: {message}"
            else:
                line = self.first_row_line + row
        elif header:
            line = self.header_line
        raise InputFileError(message, path=self.path, line=line, field=field)


def as_vector(values, name: str, place: Place) -> np.ndarray:
    """``values`` as a float array of shape (N,) (a row or column matrix is flattened), else refused."""
    array = np.asarray(values)
    if array.ndim == 2 and 1 in array.shape:
        array = array.reshape(-1)
    if array.ndim != 1 or array.dtype.kind not in "biuf":
        place.fail(f"expected a 1-D numeric array, got shape {array.shape} of {array.dtype}", name)
    return array.astype(float)


def check_metadata(meta: Mapping[str, str], place: Place) -> None:
    """Refuse metadata that breaks the format: its ``format``, ``sample_time_s``, ``loop`` and the
    proportional controller's constants."""
    fmt = meta.get("format")
    if fmt is None:
        place.fail(f"missing metadata 'format'; expected '# format: {FORMAT}' before the header",
                   "format", header=True)
    if fmt != FORMAT:
        what = "unknown format version" if fmt.startswith("pneusim-recording/") else "unknown format"
        place.fail(f"{what} {fmt!r}; expected {FORMAT!r}", "format", key="format")
    place.problem(rules.check_sample_time(meta.get("sample_time_s")))
    if "loop" in meta and meta["loop"] not in ("open", "closed"):
        place.fail(f"expected 'open' or 'closed', got {meta['loop']!r}", "loop", key="loop")
    if "controller" in meta:
        if meta["controller"] != "proportional":
            place.fail(f"unknown controller {meta['controller']!r}; expected 'proportional'",
                       "controller", key="controller")
        for key in CONTROLLER_KEYS:
            if key not in meta:
                place.fail(f"'controller: proportional' needs the constant {key!r} in the metadata "
                           f"(all of {', '.join(CONTROLLER_KEYS)})", key, key="controller")
            finite_number(meta, key, place)
        if float(meta["u_min_V"]) > float(meta["u_max_V"]):
            place.fail("u_min_V must not exceed u_max_V", "u_min_V", key="u_min_V")


def finite_number(meta: Mapping[str, str], key: str, place: Place) -> float:
    """Metadata ``key`` as a finite number, else refused."""
    text = meta[key]
    value = float(text) if rules.NUMBER.match(text) else math.nan
    if not math.isfinite(value):
        place.fail(f"expected a finite number, got {text!r}", key, key=key)
    return value


def check_columns(cols: Mapping[str, np.ndarray], meta: Mapping[str, str], place: Place,
                  stroke_m: float | None, min_samples: int = MIN_SAMPLES) -> None:
    """Refuse columns that break the format: a required one missing, lengths that differ, fewer than
    ``min_samples`` samples, values the format's rules refuse, positions beyond ``stroke_m`` [m]
    (``None``: no range check)."""
    required = REQUIRED_COLUMNS + (("reference_m",) if meta.get("loop") == "closed" else ())
    for name in required:
        if name not in cols:
            why = " (required by 'loop: closed')" if name == "reference_m" else ""
            place.fail(f"required column {name!r} missing{why}; columns present: {', '.join(cols)}",
                       name, header=True)
    n = cols["time_s"].shape[0]
    for name, values in cols.items():
        if values.shape[0] != n:
            place.fail(f"has {values.shape[0]} samples but time_s has {n}", name)
    if n < min_samples:
        place.fail(f"only {n} samples; a recording needs at least {min_samples}", "time_s", header=True)
    place.problem(rules.check_values(cols, required, None))
    place.problem(rules.check_time(cols["time_s"], float(meta["sample_time_s"])))
    place.problem(rules.check_values({"position_m": cols["position_m"]}, required, stroke_m))
