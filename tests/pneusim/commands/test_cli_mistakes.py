"""The command line as a new user meets it: user mistakes end in one line and exit 2, never a
traceback; recordings carry what made them and ``--like`` repeats it; the commands a user reaches for."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pneusim.cli import main
from pneusim.recording import read_recording
from pneusim.rig import known_rig_names, load_rig
from pneusim.scenario import load_scenario, validate_scenario

PNEUSIM = str(Path(sys.executable).with_name("pneusim"))
SIM = ["simulate", "--rig", "paper1-mre", "--input", "steps", "--duration", "0.1"]


def _one_line_error(argv, capsys, tmp_path, monkeypatch) -> str:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


@pytest.mark.parametrize("option, words", [
    (["--duration", "nan"], "argument --duration: expected a duration in s > 0, got 'nan'"),
    (["--duration", "inf"], "got 'inf'"),
    (["--duration", "-2"], "got '-2'"),
    (["--seed", "-1"], "argument --seed: expected a whole number >= 0"),
    (["--seed", "1.5"], "argument --seed"),
    (["--backend", "euler"], "argument --backend: invalid choice: 'euler'"),
    (["--noise-scale", "nan"], "argument --noise-scale: expected a finite number >= 0"),
    (["--noise-scale", "-1"], "argument --noise-scale"),
    (["--param", "moving_mas_kg=1"], "did you mean 'moving_mass_kg'"),
    (["--effect", "valve_dynamics:damping=0"], "parameter damping must be > 0"),
    (["--effect", "transport_delay:delay_s=-0.01"], "parameter delay_s must be in [0, 10]"),
    (["--duration", "1e9"], "fit in memory as a recording"),
])
def test_simulate_option_mistakes_are_one_line(option, words, capsys, tmp_path, monkeypatch):
    last = _one_line_error(SIM + option + ["--out", "x.csv"], capsys, tmp_path, monkeypatch)
    assert words in last and last.startswith("pneusim simulate: error:")
    assert not (tmp_path / "x.csv").exists()


def test_noise_scale_nan_in_a_scenario_is_refused_before_running(tmp_path):
    scenario = Path(__file__).resolve().parents[1] / "scenario" / "data" / "tiny-open-loop.toml"
    spec = load_scenario(scenario)
    for value in (float("nan"), float("inf"), -1.0):
        spec["experiment"]["noise_scale"] = value
        with pytest.raises(Exception) as err:
            validate_scenario(spec, where="s.toml")
        assert "experiment.noise_scale" in str(err.value) and "finite number >= 0" in str(err.value)
    spec["experiment"]["noise_scale"] = 0.5
    spec["experiment"]["duration_s"] = float("inf")
    with pytest.raises(Exception, match="experiment.duration_s"):
        validate_scenario(spec, where="s.toml")


def test_check_piped_into_head_ends_quietly(tmp_path):
    out = tmp_path / "r.csv"
    assert main(SIM + ["--out", str(out)]) == 0
    # far more than a pipe buffer of summaries, so that check writes after head has gone
    command = f"{PNEUSIM} check {' '.join([str(out)] * 400)} | head -n 1"
    done = subprocess.run(["bash", "-o", "pipefail", "-c", command], capture_output=True, text=True, timeout=120)
    assert done.stdout.startswith(f"{out}: valid") and done.stderr == "" and done.returncode == 0


def test_recordings_carry_what_made_them_and_like_repeats_it(tmp_path, capsys):
    first, again, plain = tmp_path / "first.csv", tmp_path / "again.csv", tmp_path / "plain.csv"
    assert main(["simulate", "--rig", "paper1-mre", "--input", "pulses", "--loop", "open", "--duration", "1",
                 "--param", "moving_mass_kg=1.5", "--param", "friction_coulomb_N=20",
                 "--effect", "valve_deadband:deadband_V=0.3", "--seed", "7", "--noise-scale", "0.5",
                 "--out", str(first)]) == 0
    meta = read_recording(first).metadata
    assert meta["rig_overrides"] == "friction_coulomb_N=20.0;moving_mass_kg=1.5"
    assert meta["effects"] == "valve_deadband:deadband_V=0.3" and meta["seed"] == "7"
    assert meta["noise_scale"] == "0.5" and meta["generator"].startswith("pneusim ")
    assert meta["command"].startswith("pneusim simulate --rig paper1-mre --input pulses")
    assert main(["simulate", "--like", str(first), "--out", str(again)]) == 0
    assert main(["simulate", "--like", str(first), "--rig", "paper1-mre", "--effect", "leakage:conductance_kg_per_s_Pa=0",
                 "--out", str(plain)]) == 0
    a, b, c = (read_recording(p) for p in (first, again, plain))
    for key in ("rig_overrides", "effects", "seed", "noise_scale"):
        assert b.metadata[key] == a.metadata[key], key
    assert np.array_equal(a.valve_cmd_V, b.valve_cmd_V)
    # the re-run on the same rig, overrides and effects follows the original far closer than one without them
    same = np.sqrt(np.mean((b.position_m - a.position_m) ** 2))
    other = np.sqrt(np.mean((c.position_m - a.position_m) ** 2))
    assert same < 0.2 * other, (same, other)


def test_like_honours_duration(tmp_path, capsys):
    first, short = tmp_path / "first.csv", tmp_path / "short.csv"
    assert main(["simulate", "--rig", "paper2-enfield", "--input", "steps", "--duration", "2", "--out", str(first)]) == 0
    assert main(["simulate", "--like", str(first), "--duration", "0.5", "--out", str(short)]) == 0
    rec = read_recording(short)
    assert rec.n_samples == 50 and rec.time_s[-1] == pytest.approx(0.49)
    assert np.array_equal(rec.reference_m, read_recording(first).reference_m[:50])
    capsys.readouterr()
    assert main(["simulate", "--like", str(first), "--duration", "5", "--out", str(short)]) == 2
    assert "holds only 2 s" in capsys.readouterr().err


def test_open_loop_simulate_reports_time_at_an_end_stop(tmp_path, capsys):
    out = tmp_path / "open.csv"
    assert main(["simulate", "--rig", "paper2-enfield", "--input", "steps", "--loop", "open", "--duration", "3",
                 "--seed", "2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "time at an end stop:" in text


def test_rigs_and_effects_list_parameters_with_units_and_ranges(capsys):
    assert main(["rigs", "--params"]) == 0
    out = capsys.readouterr().out
    for name in known_rig_names():
        assert f"{name}: " in out
    rig = load_rig("paper1-mre")
    for key in rig.params:
        assert key in out
    assert "moving_mass_kg" in out and "(> 0 kg)" in out and "valve_critical_pressure_ratio" in out
    assert main(["effects"]) == 0
    out = capsys.readouterr().out
    from pneusim.model.effects import EFFECTS
    for name, cls in EFFECTS.items():
        assert f"{name}: " in out
        for key in cls.parameters:
            assert key in out
    assert "deadband_V" in out and "(>= 0)" in out


@pytest.mark.slow
def test_plot_draws_an_existing_recording(tmp_path, capsys):
    rec = tmp_path / "r.csv"
    assert main(SIM + ["--out", str(rec)]) == 0
    for suffix in (".png", ".svg"):
        fig = tmp_path / f"r{suffix}"
        assert main(["plot", str(rec), "--out", str(fig)]) == 0
        assert fig.stat().st_size > 5_000
    capsys.readouterr()
    assert main(["plot", str(rec), "--out", str(tmp_path / "r.txt")]) == 2
    assert "expected a .png or .svg" in capsys.readouterr().err
