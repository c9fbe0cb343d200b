"""Tests of pneusim.recording: every way a recording file can break the pneusim-recording/1 contract
(shared/spec/recording-format.md) is refused with one error naming the file, line and field."""

from __future__ import annotations

import numpy as np
import pytest

from pneusim.errors import InputFileError
from pneusim.recording import read_recording

from recording_cases import CLOSED_META, COLUMNS, N, table, csv_text, row_line, refused, meta_without, meta_with


# ------------------------------------------------------------------ refusals: metadata
@pytest.mark.parametrize("key", ["format", "sample_time_s"])
def test_missing_required_metadata(write, key):
    meta = meta_without(key)
    err = refused(write(csv_text(meta)))
    assert err.field == key and err.line == len(meta) + 1 and key in err.reason


def test_unknown_format_version(write):
    err = refused(write(csv_text(meta_with("format", "pneusim-recording/2"))))
    assert err.field == "format" and err.line == 1 and "version" in err.reason
    assert "pneusim-recording/1" in err.reason


@pytest.mark.parametrize("value", ["abc", "0", "-0.01", "nan", "inf", ""])
def test_bad_sample_time(write, value):
    err = refused(write(csv_text(meta_with("sample_time_s", value))))
    assert err.field == "sample_time_s" and err.line == 2


@pytest.mark.parametrize("line", ["# just a comment", "#", "# key value", "# 1x: y"])
def test_metadata_line_not_key_value(write, line):
    text = csv_text().split("\n")
    text.insert(3, line)
    err = refused(write("\n".join(text)))
    assert err.line == 4 and "# key: value" in err.reason


def test_repeated_metadata_key(write):
    err = refused(write(csv_text(CLOSED_META + [("rig", "paper1-mre")])))
    assert err.field == "rig" and err.line == len(CLOSED_META) + 1


def test_loop_must_be_open_or_closed(write):
    err = refused(write(csv_text(meta_with("loop", "half"))))
    assert err.field == "loop" and err.line == 4 and "open" in err.reason


@pytest.mark.parametrize("key", ["kp_V_per_m", "u0_V", "u_min_V", "u_max_V"])
def test_proportional_controller_needs_its_constants(write, key):
    err = refused(write(csv_text(meta_without(key))))
    assert err.field == key and err.line == 5


def test_controller_constant_not_numeric(write):
    err = refused(write(csv_text(meta_with("kp_V_per_m", "sixty"))))
    assert err.field == "kp_V_per_m" and err.line == 6


def test_unknown_controller(write):
    err = refused(write(csv_text(meta_with("controller", "pid"))))
    assert err.field == "controller" and err.line == 5


# ------------------------------------------------------------------ refusals: header
@pytest.mark.parametrize("column", ["time_s", "valve_cmd_V", "position_m", "reference_m"])
def test_required_column_missing(write, column):
    cols = [c for c in COLUMNS if c != column]
    err = refused(write(csv_text(columns=cols)))
    assert err.field == column and err.line == len(CLOSED_META) + 1 and "missing" in err.reason


def test_duplicated_column(write):
    err = refused(write(csv_text(columns=COLUMNS + ["position_m"])))
    assert err.field == "position_m" and err.line == len(CLOSED_META) + 1 and "duplicated" in err.reason


def test_no_header(write):
    err = refused(write("".join(f"# {k}: {v}\n" for k, v in CLOSED_META)))
    assert err.line == len(CLOSED_META) + 1 and "header" in err.reason


# ------------------------------------------------------------------ refusals: cells
@pytest.mark.parametrize("column", ["time_s", "reference_m", "valve_cmd_V", "position_m", "pressure_a_Pa"])
@pytest.mark.parametrize("cell", ["abc", "1,5e", "1_0", "--1", "0x10", "1.2.3"])
def test_non_numeric_cell(write, column, cell):
    cells = table()
    cells[column][17] = cell.replace(",", ";")
    err = refused(write(csv_text(cells=cells)))
    assert err.field == column and err.line == row_line(17)


@pytest.mark.parametrize("column", ["time_s", "reference_m", "valve_cmd_V", "position_m"])
@pytest.mark.parametrize("cell", ["", " ", "nan", "NaN", "inf", "-inf"])
def test_empty_nan_inf_in_required_column(write, column, cell):
    cells = table()
    cells[column][9] = cell
    err = refused(write(csv_text(cells=cells)))
    assert err.field == column and err.line == row_line(9)


def test_inf_in_optional_column(write):
    cells = table()
    cells["pressure_b_Pa"][11] = "inf"
    err = refused(write(csv_text(cells=cells)))
    assert err.field == "pressure_b_Pa" and err.line == row_line(11)


@pytest.mark.parametrize("delta", [-1, 1])
def test_row_with_wrong_number_of_cells(write, delta):
    lines = csv_text().split("\n")
    r = row_line(20)
    lines[r - 1] = lines[r - 1] + ",1" if delta > 0 else lines[r - 1].rsplit(",", 1)[0]
    err = refused(write("\n".join(lines)))
    assert err.line == r and "cells" in err.reason
    if delta < 0:
        assert err.field == COLUMNS[-1]


def test_blank_row_in_the_middle(write):
    lines = csv_text().split("\n")
    lines.insert(row_line(30) - 1, "")
    err = refused(write("\n".join(lines)))
    assert err.line == row_line(30)


# ------------------------------------------------------------------ refusals: time
@pytest.mark.parametrize("new", ["0.29", "0.3"])
def test_time_not_strictly_increasing(write, new):
    cells = table()
    cells["time_s"][31] = new  # previous sample is 0.30
    err = refused(write(csv_text(cells=cells)))
    assert err.field == "time_s" and err.line == row_line(31) and "increasing" in err.reason


def test_time_not_uniform(write):
    cells = table()
    cells["time_s"][40] = repr(0.40 + 2e-8)  # 2e-6 relative to 0.01 s
    err = refused(write(csv_text(cells=cells)))
    assert err.field == "time_s" and err.line == row_line(40) and "uniform" in err.reason


def test_time_uniform_within_tolerance_accepted(write):
    cells = table()
    cells["time_s"][40] = repr(0.40 + 5e-9)  # 0.5e-6 relative
    read_recording(write(csv_text(cells=cells)))


def test_spacing_disagrees_with_sample_time(write):
    err = refused(write(csv_text(meta_with("sample_time_s", "0.001"))))
    assert err.field == "sample_time_s" and err.line == 2 and "spacing" in err.reason


def test_fewer_than_50_samples(write):
    cells = {k: v[:49] for k, v in table().items()}
    err = refused(write(csv_text(cells=cells)))
    assert err.field == "time_s" and "50" in err.reason and "49" in err.reason


# ------------------------------------------------------------------ refusals: ranges
@pytest.mark.parametrize("value", ["150.0", "3.2", "-0.01", "0.31"])
def test_position_outside_stroke_of_known_rig(write, value):
    cells = table()
    cells["position_m"][25] = value
    err = refused(write(csv_text(cells=cells)))
    assert err.field == "position_m" and err.line == row_line(25)
    assert "millimetres or volts" in err.reason


def test_stroke_argument_overrides_rig(write):
    path = write(csv_text(meta_without("rig")))
    read_recording(path)
    err = refused(path, stroke_m=0.1)
    assert err.field == "position_m" and err.line == row_line(0, meta_without("rig"))


@pytest.mark.parametrize("column", ["pressure_a_Pa", "pressure_b_Pa", "supply_Pa"])
@pytest.mark.parametrize("value", ["-100.0", "2000001", "5e6"])
def test_pressure_out_of_range(write, column, value):
    cells = table()
    cells["supply_Pa"] = ["6e5"] * N
    cells[column][12] = value
    err = refused(write(csv_text(cells=cells)))
    assert err.field == column and err.line == row_line(12) and "gauge" in err.reason


def test_pressure_limits_accepted(write):
    cells = table()
    cells["pressure_a_Pa"][1], cells["pressure_b_Pa"][1] = "0", "2e6"
    read_recording(write(csv_text(cells=cells)))


# ------------------------------------------------------------------ refusals: files
def test_file_not_found(tmp_path):
    err = refused(tmp_path / "nope.csv")
    assert "not found" in err.reason


def test_unknown_suffix(write):
    err = refused(write(csv_text(), name="rec.txt"))
    assert ".csv" in err.reason and ".mat" in err.reason


def test_not_utf8(write):
    data = csv_text(meta_with("description", "caf\xe9")).encode("latin-1")
    err = refused(write(data))
    assert err.line == 10 and "UTF-8" in err.reason


def test_empty_file(write):
    refused(write(""))


def _mat(tmp_path, **overrides):
    import scipy.io

    n = 60
    data = {"format": "pneusim-recording/1", "sample_time_s": 0.01, "rig": "paper2-enfield", "loop": "open",
            "time_s": np.arange(n) * 0.01, "valve_cmd_V": np.full(n, 5.0), "position_m": np.full(n, 0.1)}
    data.update(overrides)
    path = tmp_path / "r.mat"
    scipy.io.savemat(path, {k: v for k, v in data.items() if v is not None}, oned_as="column")
    return path


@pytest.mark.parametrize("overrides, field, words", [
    ({"sample_time_s": np.array([[0.01, 0.01]])}, "sample_time_s", "a single number"),
    ({"kp_V_per_m": np.array([[1.0, 2.0, 3.0]]), "loop": "closed"}, "kp_V_per_m", "a single number"),
    ({"position_m": np.zeros((0, 1))}, "position_m", "empty"),
])
def test_mat_variables_of_the_wrong_size_are_named_for_what_they_are(tmp_path, overrides, field, words):
    """A 1x2 sample_time_s used to be called 'missing', an empty position_m 'expected numeric ... got float64'."""
    with pytest.raises(InputFileError) as err:
        read_recording(_mat(tmp_path, **overrides))
    assert err.value.field == field and words in err.value.reason
    assert "missing" not in err.value.reason and "got MATLAB type" not in err.value.reason
