import math
import warnings

import numpy as np
import pytest

import sysid


def test_iddata_holds_signals_and_slices():
    y = np.arange(10.0)
    u = np.ones(10)
    d = sysid.iddata(y, u, 0.5, output_name="position_m", output_unit="m")
    assert len(d) == 10 and d.Ts == 0.5
    est, val = d.split(6)
    assert est.N == 6 and val.N == 4
    assert val.tstart == pytest.approx(3.0)
    np.testing.assert_allclose(val.time, [3.0, 3.5, 4.0, 4.5])
    assert d[2:5].y.tolist() == [2.0, 3.0, 4.0]


def test_detrend_removes_mean_and_line():
    t = np.arange(100.0)
    d = sysid.iddata(3 + 2 * t, 5 + 0 * t, 1.0)
    assert abs(d.detrend(0).u).max() < 1e-12
    assert abs(sysid.detrend(d, 1).y).max() < 1e-9


def test_load_recording_reads_metadata_and_columns(tmp_path):
    p = tmp_path / "rec.csv"
    t = np.arange(60) * 0.01
    lines = ["# format: pneusim-recording/1", "# sample_time_s: 0.01", "# rig: paper1-mre",
             "time_s,valve_cmd_V,position_m,pressure_a_Pa"]
    lines += [f"{ti:.3f},{5 + np.sin(ti):.5f},{0.05 + 0.01 * ti:.5f},400000" for ti in t]
    p.write_text("\n".join(lines) + "\n")
    d = sysid.load_recording(p)
    assert d.Ts == 0.01 and d.N == 60
    assert d.output_name == "position_m" and d.input_name == "valve_cmd_V"
    assert d.metadata["rig"] == "paper1-mre"
    assert d.y[1] == pytest.approx(0.05 + 0.01 * 0.01)


def test_load_recording_rejects_missing_column(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("# format: pneusim-recording/1\n# sample_time_s: 0.01\ntime_s,valve_cmd_V\n0,5\n")
    with pytest.raises(sysid.SysidError, match="position_m"):
        sysid.load_recording(p)


def test_load_recording_rejects_time_not_matching_sample_time(tmp_path):
    p = tmp_path / "bad_time.csv"
    rows = [f"{0.02 * i:.2f},5.0,0.1" for i in range(60)]
    p.write_text("# format: pneusim-recording/1\n# sample_time_s: 0.01\ntime_s,valve_cmd_V,position_m\n"
                 + "\n".join(rows) + "\n")
    with pytest.raises(sysid.SysidError, match="time_s"):
        sysid.load_recording(p)


def test_load_practice_recording_and_identify(real_data_dir):
    practice = real_data_dir.parent.parent / "practice" / "practice_01.csv"
    if not practice.is_file():
        pytest.skip(f"practice recording {practice} is absent")
    d = sysid.load_recording(practice)
    assert d.Ts in (0.001, 0.01) and d.N >= 8000
    assert d.output_unit == "m" and d.input_unit == "V"
    d = d.detrend()
    m = sysid.arx(d, [3, 3, 1])
    assert sysid.compare(d, m, k=1) > 90.0


def _mat_recording(path, **override):
    from scipy.io import savemat
    t = np.arange(80) * 0.01
    v = {"format": "pneusim-recording/1", "sample_time_s": 0.01, "rig": "paper2-enfield",
         "time_s": t[:, None], "valve_cmd_V": (5 + np.sin(t))[:, None], "position_m": (0.1 + 0.01 * t)[:, None]}
    v.update(override)
    savemat(path, {k: val for k, val in v.items() if val is not None})
    return t


def test_load_recording_reads_matlab_form(tmp_path):
    t = _mat_recording(tmp_path / "rec.mat")
    d = sysid.load_recording(tmp_path / "rec.mat")
    assert d.Ts == 0.01 and d.N == 80 and d.metadata["rig"] == "paper2-enfield"
    np.testing.assert_allclose(d.u, 5 + np.sin(t))
    assert d.output_unit == "m"


@pytest.mark.parametrize("override,match", [
    (dict(time_s=None), "required variable 'time_s'"),
    (dict(format="pneusim-recording/2"), "metadata 'format' must be"),
    (dict(position_m=np.r_[np.full(79, 0.1), np.nan][:, None]), r"'position_m' must be finite, but element 80"),
])
def test_load_recording_refuses_bad_matlab_form(tmp_path, override, match):
    _mat_recording(tmp_path / "bad.mat", **override)
    with pytest.raises(sysid.SysidError, match=match):
        sysid.load_recording(tmp_path / "bad.mat")


def test_load_recording_requires_time_and_finite_cells(tmp_path):
    head = "# format: pneusim-recording/1\n# sample_time_s: 0.01\n"
    p = tmp_path / "no_time.csv"
    p.write_text(head + "valve_cmd_V,position_m\n" + "5.0,0.1\n" * 60)
    with pytest.raises(sysid.SysidError, match="required column 'time_s'"):
        sysid.load_recording(p)
    p = tmp_path / "nan.csv"
    rows = [f"{0.01 * i:.2f},5.0,{'nan' if i == 30 else '0.1'}" for i in range(60)]
    p.write_text(head + "time_s,valve_cmd_V,position_m\n" + "\n".join(rows) + "\n")
    with pytest.raises(sysid.SysidError, match=r"nan.csv:34: column 'position_m' must be finite"):
        sysid.load_recording(p)


# ------------------------------------------------------------------ values the containers refuse
def test_complex_signal_is_refused_not_cast():
    """numpy's cast would drop the imaginary part with only a ComplexWarning."""
    y = np.ones(10, complex)
    y[4] = 1 + 2j
    with warnings.catch_warnings():
        warnings.simplefilter("error")                      # no ComplexWarning on the way
        with pytest.raises(sysid.SysidError, match=r"^y must be real, but sample 4 is \(1\+2j\) \(complex\)"):
            sysid.iddata(y, np.ones(10), 1.0)
        with pytest.raises(sysid.SysidError, match=r"^u must be real"):
            sysid.iddata(np.ones(10), np.full(10, 1j), 1.0)
        d = sysid.iddata(np.arange(10) + 0j, np.ones(10), 1.0)   # no imaginary part to lose
    assert d.y.dtype == float and d.y[3] == 3.0


def test_text_signal_is_refused_not_parsed():
    with pytest.raises(sysid.SysidError, match=r"^y must be a numeric 1-D array, got text"):
        sysid.iddata(["1.0", "2.0", "3.0"], [1.0, 2.0, 3.0], 1.0)


@pytest.mark.parametrize("ts", [True, False, np.True_, "0.5", [0.5], 1 + 0j, math.inf])
def test_sample_time_must_be_one_real_number(ts):
    """float() would take Ts = True as 1 s and parse '0.5'."""
    with pytest.raises(sysid.SysidError, match=r"^Ts must be a positive number of seconds"):
        sysid.iddata(np.zeros(10), np.zeros(10), ts)


def test_sample_time_from_numpy_is_a_float():
    for ts in (np.float64(0.5), np.float32(0.5), np.array(0.5), np.int64(2)):
        d = sysid.iddata(np.zeros(10), np.zeros(10), ts)
        assert type(d.Ts) is float and d.Ts == float(ts)
    with pytest.raises(sysid.SysidError, match="^tstart must be a finite number of seconds"):
        sysid.iddata(np.zeros(10), np.zeros(10), 1.0, tstart=math.nan)


def test_iddata_copies_rather_than_freezes_the_callers_arrays():
    y, u = np.arange(10.0), np.ones(10)
    d = sysid.iddata(y, u, 1.0)
    y[0] = 5.0                                               # still the caller's to write
    assert d.y[0] == 0.0 and not d.y.flags.writeable


@pytest.mark.parametrize("make,match", [
    (lambda: sysid.idpoly([1, -0.5], [0, 1], Ts=True), "^Ts must be a positive number of seconds"),
    (lambda: sysid.idpoly([1, -0.5], [0, 1], Ts=0.0), "^Ts must be a positive number of seconds"),
    (lambda: sysid.idpoly([1, -0.5j], [0, 1]), "^A must be a 1-D array of real coefficients"),
    (lambda: sysid.idpoly([1, -0.5], "01"), "^B must be a 1-D array of real coefficients"),
    (lambda: sysid.IDSS(np.eye(2), np.ones((2, 1)), np.ones((1, 2)), np.zeros((1, 1)), np.zeros((2, 1)), Ts=-1),
     "^Ts must be a positive number of seconds"),
    (lambda: sysid.IDSS(np.eye(2), np.ones((3, 1)), np.ones((1, 2)), np.zeros((1, 1)), np.zeros((2, 1))),
     r"^B must have shape \(2, 1\) for a model with 2 states"),
    (lambda: sysid.IDSS(np.ones((2, 3)), np.ones((2, 1)), np.ones((1, 2)), 0.0, np.zeros((2, 1))),
     "^A must be a square matrix"),
    (lambda: sysid.IDTF(np.array([1.0]), np.array([1.0, 1.0]), Ts=0.0), "^Ts must be a positive number"),
    (lambda: sysid.IDTF(np.array([1.0]), np.array([1.0, 1.0]), iodelay=-0.1), "^iodelay must be a non-negative"),
    (lambda: sysid.IDTF(np.array([1.0, 0.0]), np.array([1.0, 1.0])), "^num must have a lower degree than den"),
    (lambda: sysid.IDTF(np.array([1.0]), np.array([2.0, 1.0])), "^den must be monic"),
])
def test_model_constructors_check_their_values(make, match):
    with pytest.raises(sysid.SysidError, match=match):
        make()
