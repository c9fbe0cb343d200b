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
