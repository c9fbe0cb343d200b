"""Shared pieces of the recording tests (``test_recording.py``, ``test_recording_refusals.py``): a
valid closed-loop recording as CSV text, ways to break it, and the check that a refusal names the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pneusim.errors import InputFileError
from pneusim.recording import read_recording

PRACTICE = Path(__file__).resolve().parents[2].parent / "shared" / "practice"

CLOSED_META = [
    ("format", "pneusim-recording/1"), ("sample_time_s", "0.01"), ("rig", "paper2-enfield"),
    ("loop", "closed"), ("controller", "proportional"), ("kp_V_per_m", "60.0"), ("u0_V", "5.0"),
    ("u_min_V", "0.0"), ("u_max_V", "10.0"), ("description", "test: a, b"),
]
COLUMNS = ["time_s", "reference_m", "valve_cmd_V", "position_m", "pressure_a_Pa", "pressure_b_Pa"]
N = 60


def table(n=N, dt=0.01):
    """Valid numeric cells as text, {column: [cell, ...]} (paper2-enfield: stroke 0.3048 m)."""
    i = np.arange(n)
    t = np.round(i * dt, 10)
    return {
        "time_s": [repr(float(v)) for v in t],
        "reference_m": ["0.15"] * n,
        "valve_cmd_V": [repr(float(v)) for v in 5.0 + 0.1 * np.sin(i)],
        "position_m": [repr(float(v)) for v in 0.15 + 0.01 * np.cos(i)],
        "pressure_a_Pa": [repr(float(v)) for v in 4e5 + 1e3 * np.sin(i)],
        "pressure_b_Pa": [repr(float(v)) for v in 3e5 + 1e3 * np.cos(i)],
    }


def csv_text(meta=CLOSED_META, cells=None, columns=None):
    cells = table() if cells is None else cells
    columns = list(cells) if columns is None else columns
    lines = [f"# {k}: {v}" for k, v in meta]
    lines.append(",".join(columns))
    n = len(cells[columns[0]]) if columns else 0
    lines += [",".join(cells[c][r] for c in columns) for r in range(n)]
    return "\n".join(lines) + "\n"


def row_line(r, meta=CLOSED_META):
    """CSV line (1-based) of data row r (0-based)."""
    return len(meta) + 2 + r


def refused(path, **kwargs):
    with pytest.raises(InputFileError) as info:
        read_recording(path, **kwargs)
    err = info.value
    assert str(path) in str(err)
    return err


def meta_without(key):
    return [(k, v) for k, v in CLOSED_META if k != key]


def meta_with(key, value):
    return [(k, value if k == key else v) for k, v in CLOSED_META]
