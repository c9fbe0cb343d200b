"""Tests of pneusim.recording: the pneusim-recording/1 contract (shared/spec/recording-format.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pneusim.errors import InputFileError
from pneusim.recording import Recording, read_recording, summarize, write_recording

from recording_cases import PRACTICE, CLOSED_META, COLUMNS, N, table, csv_text, refused, meta_with


# ------------------------------------------------------------------ valid input
def test_valid_file_loads(write):
    rec = read_recording(write(csv_text()))
    assert rec.n_samples == len(rec) == N
    assert rec.sample_time_s == 0.01 and rec.rig == "paper2-enfield" and rec.loop == "closed"
    assert rec.controller == {"kp_V_per_m": 60.0, "u0_V": 5.0, "u_min_V": 0.0, "u_max_V": 10.0}
    assert rec.has_pressures and rec.supply_Pa is None
    assert rec.metadata["description"] == "test: a, b"
    assert rec.time_s.shape == (N,) and rec.time_s.dtype == float
    assert list(rec.columns()) == COLUMNS


def test_column_order_is_free_and_extras_and_unknown_keys_kept(write):
    cells = table()
    cells["temp_K"] = ["293.5"] * N
    meta = CLOSED_META + [("operator", "Ann")]
    cols = ["position_m", "temp_K", "valve_cmd_V", "time_s", "reference_m"]
    rec = read_recording(write(csv_text(meta, cells, cols)))
    assert rec.metadata["operator"] == "Ann"
    np.testing.assert_array_equal(rec.extra["temp_K"], np.full(N, 293.5))
    assert not rec.has_pressures and rec.pressure_a_Pa is None


def test_open_loop_needs_no_reference(write):
    meta = [("format", "pneusim-recording/1"), ("sample_time_s", "0.01"), ("loop", "open")]
    rec = read_recording(write(csv_text(meta, columns=["time_s", "valve_cmd_V", "position_m"])))
    assert rec.loop == "open" and rec.controller is None and rec.reference_m is None


def test_gaps_in_optional_columns_are_kept_as_nan(write):
    cells = table()
    cells["pressure_a_Pa"][5] = ""
    cells["pressure_b_Pa"][7] = "nan"
    rec = read_recording(write(csv_text(cells=cells)))
    assert np.isnan(rec.pressure_a_Pa[5]) and np.isnan(rec.pressure_b_Pa[7])
    assert rec.gap_mask("pressure_a_Pa").sum() == 1 and rec.gap_mask("pressure_a_Pa")[5]
    assert "gaps: 1" in summarize(rec)


def test_exactly_50_samples_accepted(write):
    cells = {k: v[:50] for k, v in table().items()}
    assert read_recording(write(csv_text(cells=cells))).n_samples == 50


def test_position_at_stroke_limits_accepted_and_unknown_rig_not_checked(write):
    cells = table()
    stroke = 0.3048
    cells["position_m"][3] = repr(-0.0099 * stroke)
    cells["position_m"][4] = repr(1.0099 * stroke)
    read_recording(write(csv_text(cells=cells)))
    cells["position_m"][5] = "150.0"  # millimetres, but the rig is unknown
    read_recording(write(csv_text(meta_with("rig", "my-own-rig"), cells=cells)))


def test_crlf_and_bom_accepted(write):
    text = csv_text().replace("\n", "\r\n").encode("utf-8")
    assert read_recording(write(b"\xef\xbb\xbf" + text)).n_samples == N


# ------------------------------------------------------------------ .mat
def mat_vars(n=N):
    rec = read_recording_from_cells(table(n))
    out = {k: v for k, v in rec.metadata.items() if k != "sample_time_s"}
    out["sample_time_s"] = 0.01
    out.update({k: v.reshape(-1, 1) for k, v in rec.columns().items()})
    return out


def read_recording_from_cells(cells):
    cols = {k: np.array(v, dtype=float) for k, v in cells.items()}
    return Recording(**cols, metadata=dict(CLOSED_META))


def save_mat(path, variables):
    import scipy.io
    scipy.io.savemat(path, variables)
    return path


def test_mat_written_by_matlab_user_loads(tmp_path):
    variables = mat_vars()
    variables["kp_V_per_m"] = 60.0  # a number, not text
    rec = read_recording(save_mat(tmp_path / "r.mat", variables))
    assert rec.controller["kp_V_per_m"] == 60.0 and rec.loop == "closed" and rec.has_pressures


@pytest.mark.parametrize("name", ["format", "sample_time_s", "time_s", "reference_m"])
def test_mat_missing_variable(tmp_path, name):
    variables = mat_vars()
    del variables[name]
    err = refused(save_mat(tmp_path / "r.mat", variables))
    assert err.field == name


def test_mat_bad_cell_names_variable_and_sample(tmp_path):
    variables = mat_vars()
    variables["position_m"][7, 0] = np.nan
    err = refused(save_mat(tmp_path / "r.mat", variables))
    assert err.field == "position_m" and "sample 8" in err.reason


def test_mat_length_mismatch_and_matrix(tmp_path):
    variables = mat_vars()
    variables["valve_cmd_V"] = variables["valve_cmd_V"][:-1]
    assert refused(save_mat(tmp_path / "a.mat", variables)).field == "valve_cmd_V"
    variables = mat_vars()
    variables["position_m"] = np.zeros((N, 2))
    assert refused(save_mat(tmp_path / "b.mat", variables)).field == "position_m"


def test_mat_unknown_version_and_range(tmp_path):
    variables = mat_vars()
    variables["format"] = "pneusim-recording/9"
    assert refused(save_mat(tmp_path / "a.mat", variables)).field == "format"
    variables = mat_vars()
    variables["pressure_a_Pa"] = variables["pressure_a_Pa"] - 4.5e5  # gauge, partly below atmosphere
    assert refused(save_mat(tmp_path / "b.mat", variables)).field == "pressure_a_Pa"


def test_damaged_mat(write):
    refused(write(b"not a mat file at all", name="r.mat"))


# ------------------------------------------------------------------ construction
def test_construction_validates():
    t = np.arange(60) * 0.01
    with pytest.raises(InputFileError) as info:
        Recording(time_s=t, valve_cmd_V=np.zeros(59), position_m=np.zeros(60), metadata={"sample_time_s": "0.01"})
    assert info.value.path is None and info.value.field == "valve_cmd_V"
    t2 = t.copy()
    t2[10] = t2[9]
    with pytest.raises(InputFileError) as info:
        Recording(time_s=t2, valve_cmd_V=np.zeros(60), position_m=np.zeros(60), metadata={"sample_time_s": "0.01"})
    assert info.value.path is None and info.value.field == "time_s" and "sample 11" in str(info.value)
    with pytest.raises(InputFileError):
        Recording(time_s=t, valve_cmd_V=np.zeros(60), position_m=np.zeros(60), metadata={})


def test_slice_columns_and_summary(write):
    rec = read_recording(write(csv_text()))
    part = rec.slice(0.1, 0.2)
    np.testing.assert_allclose(part.time_s, np.arange(10, 20) * 0.01)
    assert part.metadata == rec.metadata and part.has_pressures and len(part) == 10
    assert len(rec.slice(t_start_s=0.5)) == 10
    with pytest.raises(InputFileError):
        rec.slice(5.0, 6.0)
    text = summarize(rec)
    for word in ("60", "0.01", "paper2-enfield", "closed", "kp_V_per_m=60", "pressure_b_Pa"):
        assert word in text


# ------------------------------------------------------------------ round trips
def assert_same(a: Recording, b: Recording):
    assert list(a.columns()) == list(b.columns())
    for name, values in a.columns().items():
        np.testing.assert_array_equal(values, b.columns()[name], err_msg=name)
    assert a.sample_time_s == b.sample_time_s
    meta_a = {k: v for k, v in a.metadata.items() if k != "sample_time_s"}
    assert meta_a == {k: v for k, v in b.metadata.items() if k != "sample_time_s"}


@pytest.mark.parametrize("suffix", [".csv", ".mat"])
@pytest.mark.parametrize("variant", ["full", "minimal", "extra"])
def test_round_trip(tmp_path, suffix, variant):
    cells = table()
    if variant == "minimal":
        cells = {k: cells[k] for k in ("time_s", "valve_cmd_V", "position_m")}
        meta = [("format", "pneusim-recording/1"), ("sample_time_s", "0.01")]
    else:
        meta = CLOSED_META
    if variant == "extra":
        cells["temp_K"] = [repr(293.0 + 1 / 3 * i) for i in range(N)]
        cells["pressure_a_Pa"][3] = "nan"
        meta = meta + [("operator", "Zoë"), ("empty", "")]
    cols = {k: np.array(v, dtype=float) for k, v in cells.items()}
    extra = {"temp_K": cols.pop("temp_K")} if "temp_K" in cols else {}
    rec = Recording(**cols, metadata=dict(meta), extra=extra)
    path = tmp_path / f"r{suffix}"
    write_recording(rec, path)
    back = read_recording(path)
    assert_same(rec, back)
    write_recording(back, tmp_path / f"again{suffix}")
    assert_same(rec, read_recording(tmp_path / f"again{suffix}"))


def test_significant_digits(tmp_path):
    rec = read_recording_from_cells(table())
    rec.valve_cmd_V[:] = 5.123456789
    write_recording(rec, tmp_path / "r.csv", significant_digits=4)
    back = read_recording(tmp_path / "r.csv")
    assert np.all(back.valve_cmd_V == 5.123)
    np.testing.assert_array_equal(back.time_s, rec.time_s)


# ------------------------------------------------------------------ practice set
PRACTICE_FILES = [f"practice_{i:02d}.csv" for i in range(1, 23)]


@pytest.mark.parametrize("name", PRACTICE_FILES)
def test_practice_recordings_load(name):
    if not (PRACTICE / name).exists():
        pytest.skip("practice set not available")
    case = json.loads((PRACTICE / "answers.json").read_text())["cases"][name]
    rec = read_recording(PRACTICE / name)
    exp = case["experiment"]
    assert rec.rig == case["rig"]
    assert rec.loop == exp["loop"]
    assert rec.has_pressures == case["records_pressures"]
    assert rec.n_samples == exp["n_samples"] and rec.sample_time_s == exp["sample_time_s"]
    if exp["loop"] == "closed":
        assert rec.controller == {k: exp[k] for k in ("kp_V_per_m", "u0_V", "u_min_V", "u_max_V")}
        assert rec.reference_m is not None
    else:
        assert rec.controller is None


# ------------------------------------------------------------------ property-based
text_value = st.text(st.characters(min_codepoint=32, max_codepoint=0x2FF, blacklist_categories=("Cs", "Cc")),
                     max_size=20).map(str.strip)


@st.composite
def recordings(draw):
    n = draw(st.integers(50, 120))
    dt = draw(st.sampled_from([0.001, 0.002, 0.01, 0.05]))
    t0 = draw(st.sampled_from([0.0, 1.0, 12.5, 300.0]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    closed = draw(st.booleans())
    cols = {"time_s": t0 + np.arange(n) * dt,
            "valve_cmd_V": rng.uniform(0, 10, n),
            "position_m": rng.uniform(0, 0.1, n)}
    meta = {"sample_time_s": repr(dt), "rig": "paper1-mre", "loop": "closed" if closed else "open"}
    if closed:
        cols["reference_m"] = rng.uniform(0, 0.1, n)
        meta.update(controller="proportional", kp_V_per_m="40.0", u0_V="5.0", u_min_V="0", u_max_V="10")
    for name in ("pressure_a_Pa", "pressure_b_Pa", "supply_Pa"):
        if draw(st.booleans()):
            values = rng.uniform(0, 2e6, n)
            values[rng.random(n) < 0.05] = np.nan
            cols[name] = values
    keys = draw(st.lists(st.from_regex(r"x[a-z0-9_]{0,8}", fullmatch=True), max_size=3, unique=True))
    for key in keys:
        meta[key] = draw(text_value)
    extra = {"aux_V": rng.normal(size=n) * 10.0 ** rng.integers(-5, 5)} if draw(st.booleans()) else {}
    return Recording(**cols, metadata=meta, extra=extra)


SETTINGS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@SETTINGS
@given(rec=recordings(), suffix=st.sampled_from([".csv", ".mat"]))
def test_random_recordings_round_trip(tmp_path, rec, suffix):
    path = tmp_path / f"r{suffix}"
    write_recording(rec, path)
    assert_same(rec, read_recording(path))


@SETTINGS
@given(rec=recordings(), data=st.data())
def test_random_single_cell_corruption_refused(tmp_path, rec, data):
    path = tmp_path / "r.csv"
    write_recording(rec, path)
    lines = path.read_text().split("\n")
    header = len(rec.metadata) + 1
    names = lines[header - 1].split(",")
    name = data.draw(st.sampled_from(names))
    required = name in ("time_s", "valve_cmd_V", "position_m", "reference_m")
    bad = ["abc", "1_0", "inf", "-inf", "1e", "."] + (["", "nan"] if required else [])
    if name == "position_m":
        bad.append("100.0")  # millimetres
    if name.startswith("pressure") or name == "supply_Pa":
        bad.append("-1.0")
    cell = data.draw(st.sampled_from(bad))
    r = data.draw(st.integers(0, len(rec) - 1))
    line = header + 1 + r
    cells = lines[line - 1].split(",")
    cells[names.index(name)] = cell
    lines[line - 1] = ",".join(cells)
    path.write_text("\n".join(lines))
    with pytest.raises(InputFileError) as info:
        read_recording(path)
    assert (info.value.line, info.value.field) == (line, name)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("bad", ["two_lines", "cell"])
def test_mat_metadata_of_wrong_type(tmp_path, bad):
    variables = mat_vars()
    if bad == "two_lines":
        variables["description"] = np.array(["line one", "line two"])
    else:
        variables["description"] = np.array([["a"], [1.0]], dtype=object)
    err = refused(save_mat(tmp_path / "r.mat", variables))
    assert err.field == "description"
