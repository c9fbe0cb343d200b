"""``pneusim friction``: the real TU Delft seal data need the pressure-dependent law; constant-friction data
do not; bad files are refused in one line."""

import json

import numpy as np
import pytest

from pneusim import outputs
from pneusim.cli import main
from pneusim.friction import FrictionStudy, NOMINAL_LAW, PRESSURE_LAW, read_friction_test

HEADER = "time_ms,laser_V,pressure_V,force_V,laser_position_mm,pressure_bar_gauge,force_N"
BORE_M = 0.025


def _write_test(path, pressure_bar, k, seed, cycles=3):
    """A synthetic friction test like the TU Delft ones: strokes over about 40 mm at constant speed with
    reversals at 0.1 m/s^2 (extending slower at higher pressure, as on the real rig), sample times of 10-12 ms, a Stribeck law with one level per
    direction scaled by (1 + k p / 6 bar) / (1 + k 4 bar / 6 bar), AR(1) force noise of 0.5 N."""
    rng = np.random.default_rng(seed)
    v_out, v_in = (13.0 - 0.9 * pressure_bar) * 1e-3, 12e-3
    t, x, vel = [0.0], [0.0], [0.0]
    direction = 1
    for _ in range(20000):
        dt = rng.uniform(0.010, 0.012)
        target = v_out if direction > 0 else -v_in
        v = vel[-1] + np.clip(target - vel[-1], -0.1 * dt, 0.1 * dt)   # reversals at 0.1 m/s^2
        t.append(t[-1] + dt)
        x.append(x[-1] + v * dt)
        vel.append(v)
        if (direction > 0 and x[-1] > 0.038) or (direction < 0 and x[-1] < 0.0):
            direction = -direction
            cycles -= direction > 0
            if cycles == 0:
                break
    t, x, vel = np.array(t), np.array(x), np.array(vel)
    theta = [5.0, 3.5, 1.5, 3e-3, 50.0, 1e-3]
    law = NOMINAL_LAW
    if k:
        theta, law = theta + [k], PRESSURE_LAW
    p_pa = pressure_bar * 1e5 + rng.normal(0.0, 1e3, t.size)
    friction = law.force_N(theta, vel, p_pa, 4e5, 6e5)
    noise = np.zeros(t.size)
    e = rng.normal(0.0, 0.5 * np.sqrt(1 - 0.8 ** 2), t.size)
    for i in range(1, t.size):
        noise[i] = 0.8 * noise[i - 1] + e[i]
    force = p_pa * np.pi / 4 * BORE_M ** 2 + friction + noise
    x_noisy = x + rng.normal(0.0, 5e-6, t.size)
    rows = [f"{a * 1e3:.3f},0,0,0,{b * 1e3:.3f},{c / 1e5:.3f},{d:.3f}" for a, b, c, d in zip(t, x_noisy, p_pa, force)]
    path.write_text(HEADER + "\n" + "\n".join(rows) + "\n")
    return path


def _synthetic(folder, k, seed):
    return [_write_test(folder / f"synthetic_{p}bar.csv", p, k, seed + p) for p in (1, 3, 5, 7)]


@pytest.mark.slow
def test_real_seal_data_need_the_pressure_dependent_law(shared_dir, tmp_path, capsys):
    files = sorted((shared_dir / "data" / "real" / "cylinder_seal_friction_tudelft2021").glob("*.csv"))
    assert len(files) == 12
    out, plot = tmp_path / "friction.json", tmp_path / "friction.png"
    assert main(["friction", *map(str, files), "--json", str(out), "--plot", str(plot)]) == 0
    printed = capsys.readouterr().out
    assert "missing physics: pressure_dependent_friction" in printed
    data = json.loads(out.read_text())
    assert [f["effect"] for f in data["findings"]] == ["pressure_dependent_friction"]
    # held out: the pressure law predicts pressures it never saw clearly better, seal by seal
    assert data["held_out_rms_pressure_law_N"] < 0.75 * data["held_out_rms_nominal_N"]
    assert data["pressure_law_better_folds"] >= 9 and data["folds"] == 12
    for seal, entry in data["seals"].items():
        assert entry["pooled_rms_pressure_law_N"] < 0.8 * entry["pooled_rms_nominal_N"], seal
        k = entry["pressure_law"]["parameters"]["pressure_coefficient"]
        assert k["estimate"] > 3 * k["std"] and k["estimate"] > 0.5, (seal, k)
        # model-free: the median sliding friction extending grows from the lowest to the highest pressure
        sliding = entry["sliding_friction"]
        assert sliding[-1]["median_extending_N"] > 1.4 * sliding[0]["median_extending_N"], seal
    assert plot.stat().st_size > 20_000


def test_constant_friction_comes_back_nothing_missing(tmp_path):
    """Same friction at every pressure (speeds differing by pressure as on the real rig): the extra
    parameter must not win on held-out pressures, and its estimate stays near zero."""
    study = FrictionStudy().fit([read_friction_test(f, BORE_M) for f in _synthetic(tmp_path, 0.0, 10)])
    assert study.findings_ == []
    assert study.rms_pressure_N_ > 0.95 * study.rms_nominal_N_
    assert abs(study.seals_[0].pressure.theta[-1]) < 0.1
    assert "nothing is missing" in study.table()
    _write_json_is_atomic(study, tmp_path / "friction.json")


def _write_json_is_atomic(study, path):
    """FrictionStudy.write_json writes to_dict as JSON; a write that fails (here the rename of a full disk)
    leaves the previous file whole and no temporary file."""
    path.write_text("previous")
    assert study.write_json(path) == path and json.loads(path.read_text()) == json.loads(json.dumps(study.to_dict()))
    path.write_text("previous")
    before = sorted(p.name for p in path.parent.iterdir())

    def full_disk(src, dst):
        raise OSError(28, "No space left on device")

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(outputs.os, "replace", full_disk)
        with pytest.raises(OSError):
            study.write_json(path)
    assert path.read_text() == "previous" and sorted(p.name for p in path.parent.iterdir()) == before


def test_pressure_dependent_synthetic_friction_is_found_and_predicted(tmp_path):
    """k = 2: found, and the fitted law gives the true friction at each pressure's sliding speeds.  k itself
    is only loosely pinned (1.5-3): each file slides at one speed per direction, and the speeds change with
    pressure, so the viscous term and k share part of the pressure trend."""
    tests = [read_friction_test(f, BORE_M) for f in _synthetic(tmp_path, 2.0, 20)]
    study = FrictionStudy().fit(tests)
    assert [f["effect"] for f in study.findings_] == ["pressure_dependent_friction"]
    fit = study.seals_[0].pressure
    assert 1.5 < fit.theta[-1] < 3.0
    truth = [5.0, 3.5, 1.5, 3e-3, 50.0, 1e-3, 2.0]
    for test in tests:
        for speed in (np.median(test.velocity_m_per_s[test.velocity_m_per_s > 3e-3]),
                      np.median(test.velocity_m_per_s[test.velocity_m_per_s < -3e-3])):
            v, p = np.array([speed]), np.array([test.mean_pressure_gauge_Pa])
            expected = PRESSURE_LAW.force_N(truth, v, p, 4e5, 6e5)
            assert fit.force_N(v, p) == pytest.approx(expected, rel=0.05), (test.label, speed)


def _error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


def test_bad_files_are_refused_in_one_line(tmp_path, capsys):
    files = _synthetic(tmp_path, 0.0, 30)
    lines = files[1].read_text().splitlines()
    lines[40] = lines[40].replace(lines[40].split(",")[6], "12..5")
    files[1].write_text("\n".join(lines) + "\n")
    err = _error(capsys, ["friction", *map(str, files), "--bore", "synthetic=0.025"])
    assert files[1].name in err and "line 41" in err and "force_N" in err and "expected a number" in err

    no_force = tmp_path / "noforce_1bar.csv"
    no_force.write_text("time_ms,laser_position_mm,pressure_bar_gauge\n0,0,1\n")
    err = _error(capsys, ["friction", str(no_force), "--bore", "noforce=0.02"])
    assert "force_N" in err and "line 1" in err

    backwards = tmp_path / "back_1bar.csv"
    text = files[0].read_text().splitlines()
    text[100], text[101] = text[101], text[100]
    backwards.write_text("\n".join(text) + "\n")
    err = _error(capsys, ["friction", str(backwards), "--bore", "back=0.02"])
    assert "line 102" in err and "time_ms" in err and "does not increase" in err

    err = _error(capsys, ["friction", str(files[0])])
    assert "bore of seal 'synthetic'" in err and "--bore" in err
    err = _error(capsys, ["friction", str(files[0]), str(files[2]), "--bore", "synthetic=0.025"])
    assert "at least 3 files" in err
    err = _error(capsys, ["friction", str(files[0]), "--bore", "synthetic=25mm"])
    assert "SEAL=METRES" in err
    err = _error(capsys, ["friction", str(tmp_path / "missing_1bar.csv")])
    assert "not found" in err


def test_a_utf8_bom_file_is_read_as_check_reads_recordings(tmp_path):
    """A byte order mark before the header (Excel's 'CSV UTF-8'): pneusim check accepts it in recordings, so
    friction files take it too, with the same numbers as without."""
    plain = _write_test(tmp_path / "plain_3bar.csv", 3, 0.0, 5)
    bom = tmp_path / "bom_3bar.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    a, b = read_friction_test(plain, BORE_M), read_friction_test(bom, BORE_M)
    np.testing.assert_array_equal(a.force_N, b.force_N)
    np.testing.assert_array_equal(a.velocity_m_per_s, b.velocity_m_per_s)


def test_friction_outputs_are_never_its_inputs(tmp_path, capsys):
    files = _synthetic(tmp_path, 0.0, 40)
    before = files[0].read_bytes()
    err = _error(capsys, ["friction", *map(str, files), "--bore", "synthetic=0.025", "--json", str(files[0])])
    assert "--json" in err
    assert files[0].read_bytes() == before
