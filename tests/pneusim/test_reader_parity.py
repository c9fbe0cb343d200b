"""The two readers of pneusim-recording/1 (``pneusim.recording.read_recording`` and
``sysid.load_recording``) refuse the same files: one set of value rules (``sysid/format_rules.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sysid
from pneusim.errors import InputFileError
from pneusim.recording import read_recording
from pneusim.rig import RIG_DIR, load_rig
from sysid import format_rules

HEAD = ["# format: pneusim-recording/1", "# sample_time_s: 0.01", "# rig: paper2-enfield", "# loop: closed"]
NAMES = ["time_s", "reference_m", "valve_cmd_V", "position_m", "pressure_a_Pa", "pressure_b_Pa"]


def _lines(n=60):
    rows = [f"{0.01 * i:.2f},0.15,{5 + 0.1 * np.sin(i):.5f},{0.15 + 0.01 * np.cos(i):.5f},"
            f"{4e5 + 1e3 * np.sin(i):.1f},{3e5:.1f}" for i in range(n)]
    return HEAD + [",".join(NAMES)] + rows


def _verdicts(path: Path) -> tuple[bool, bool]:
    """(pneusim refuses, sysid refuses); any other exception than the readers' own is a bug."""
    try:
        read_recording(path)
        pneusim_refuses = False
    except InputFileError:
        pneusim_refuses = True
    try:
        sysid.load_recording(path)
        sysid_refuses = False
    except sysid.SysidError:
        sysid_refuses = True
    return pneusim_refuses, sysid_refuses


def _write(tmp_path, lines, name="r.csv") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("value", ["103.0", "1e308", "-0.5", "0.4"])
def test_positions_outside_the_stroke_are_refused_by_both(tmp_path, value):
    lines = _lines()
    cells = lines[10].split(",")
    cells[3] = value
    lines[10] = ",".join(cells)
    path = _write(tmp_path, lines)
    assert _verdicts(path) == (True, True)
    with pytest.raises(sysid.SysidError, match="position_m.*outside"):
        sysid.load_recording(path)


def test_a_binary_file_is_a_clear_error_for_both(tmp_path):
    path = tmp_path / "r.csv"
    path.write_bytes(b"# format: pneusim-recording/1\n" + bytes(range(256)) * 20)
    assert _verdicts(path) == (True, True)
    with pytest.raises(sysid.SysidError, match="not UTF-8 text"):
        sysid.load_recording(path)


@pytest.mark.parametrize("edit", [
    lambda L: L[:10],                                                          # fewer than 50 samples
    lambda L: [L[0], "# sample_time_s: -0.01"] + L[2:],
    lambda L: [L[0], "# sample_time_s: nan"] + L[2:],
    lambda L: L[:20] + [L[20].replace("0.16,", "0.17,", 1)] + L[21:],         # non-uniform time
    lambda L: L[:20] + [",".join(L[20].split(",")[:4] + ["-1.0", "3e5"])] + L[21:],  # negative pressure
    lambda L: L[:20] + [",".join(L[20].split(",")[:4] + ["5e6", "3e5"])] + L[21:],   # 50 bar written as Pa? no: 5 MPa
    lambda L: L[:20] + [",".join(L[20].split(",")[:4] + ["inf", "3e5"])] + L[21:],
    lambda L: L[:20] + [",".join(L[20].split(",")[:4] + ["", "3e5"])] + L[21:],      # a gap: accepted by both
    lambda L: L[:20] + [L[20].replace(",0.15,", ",1_0,", 1)] + L[21:],
    lambda L: L[:20] + [L[20].replace(",0.15,", ",,", 1)] + L[21:],            # empty reference in closed loop
    lambda L: L[:4] + [L[4].replace("reference_m,", "ref_m,")] + L[5:],        # closed loop without reference_m
    lambda L: L,                                                               # valid
])
def test_both_readers_agree_on_malformed_files(tmp_path, edit):
    pneusim_refuses, sysid_refuses = _verdicts(_write(tmp_path, edit(_lines())))
    assert pneusim_refuses == sysid_refuses


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(column=st.sampled_from(NAMES), row=st.integers(0, 59),
       cell=st.sampled_from(["abc", "1_0", "inf", "-inf", "nan", "", "1e", ".", "100.0", "-1.0", "3.7", "2.5e6",
                             "1e308", " 0.2 ", "+0.1"]))
def test_single_cell_changes_get_the_same_verdict(tmp_path, column, row, cell):
    lines = _lines()
    cells = lines[5 + row].split(",")
    cells[NAMES.index(column)] = cell
    lines[5 + row] = ",".join(cells)
    assert len(set(_verdicts(_write(tmp_path, lines)))) == 1


def test_the_shared_rules_know_the_shipped_rigs_strokes():
    shipped = {p.stem for p in RIG_DIR.glob("*.toml")}
    assert shipped == set(format_rules.SHIPPED_STROKES_M)
    for name in shipped:
        assert format_rules.SHIPPED_STROKES_M[name] == load_rig(RIG_DIR / f"{name}.toml").stroke_m
