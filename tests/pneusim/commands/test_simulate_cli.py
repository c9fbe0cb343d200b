"""The command line: simulate, re-run, check, and user mistakes as one-line errors."""

from pathlib import Path

import numpy as np
import pytest

from pneusim.cli import main
from pneusim.recording import read_recording


@pytest.mark.slow
def test_simulate_writes_a_valid_recording_and_plot(tmp_path, capsys):
    out, png = tmp_path / "run.csv", tmp_path / "run.png"
    assert main(["simulate", "--rig", "paper1-mre", "--input", "pulses", "--duration", "1", "--seed", "3",
                 "--out", str(out), "--plot", str(png)]) == 0
    rec = read_recording(out)
    assert rec.n_samples == 1000 and rec.loop == "closed" and rec.has_pressures
    assert png.stat().st_size > 10_000
    assert main(["check", str(out)]) == 0
    assert "valid pneusim-recording/1" in capsys.readouterr().out


def test_simulate_mat_with_param_and_effect(tmp_path):
    out = tmp_path / "run.mat"
    assert main(["simulate", "--rig", "paper2-enfield", "--input", "steps", "--loop", "open", "--duration", "2",
                 "--param", "moving_mass_kg=2.0", "--effect", "valve_deadband:deadband_V=0.5",
                 "--out", str(out)]) == 0
    rec = read_recording(out)
    assert rec.loop == "open" and "valve_deadband" in rec.metadata["effects"]


def test_like_reruns_a_recording(tmp_path, shared_dir):
    src = shared_dir / "practice" / "practice_20.csv"
    out = tmp_path / "again.csv"
    assert main(["simulate", "--like", str(src), "--out", str(out), "--noise-scale", "0"]) == 0
    original, again = read_recording(src), read_recording(out)
    assert np.array_equal(original.valve_cmd_V, again.valve_cmd_V)
    assert np.sqrt(np.mean((original.position_m - again.position_m) ** 2)) < 3e-4


@pytest.mark.parametrize("argv, message", [
    (["simulate", "--rig", "nope", "--input", "steps", "--out", "x.csv"], "unknown rig 'nope'"),
    (["simulate", "--rig", "paper1-mre", "--input", "steps", "--param", "mass=1", "--out", "x.csv"], "no parameter"),
    (["simulate", "--rig", "paper1-mre", "--input", "steps", "--param", "moving_mass_kg=heavy", "--out", "x.csv"],
     "must be a number"),
    (["simulate", "--rig", "paper1-mre", "--input", "steps", "--out", "x.txt"], "expected a .csv or .mat"),
    (["simulate", "--rig", "paper1-mre", "--out", "x.csv"], "give --input"),
    (["simulate", "--rig", "paper1-mre", "--input", "steps", "--duration", "0.01", "--out", "x.csv"], "at least 50"),
    (["check", "missing.csv"], "missing.csv"),
    (["simulate", "--rig", "paper1-mre", "--input", "steps", "--out", "no/such/folder/x.csv"],
     "the folder no/such/folder does not exist"),
    (["simulate", "--rig", "paper1-mre", "--input", "steps", "--out", "x.csv", "--plot", "x.pdf"],
     "expected a .png or .svg"),
])
def test_user_mistakes_are_one_clear_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]  # progress bars may precede it
    assert message in last and last.startswith("pneusim ") and "Traceback" not in err


def test_an_output_folder_that_cannot_be_created_is_refused_before_any_work(tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    scenario = Path(__file__).resolve().parents[3] / "scenarios" / "paper2-multisine.toml"
    assert main(["run", str(scenario), "--out", str(blocker / "report"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "the folder cannot be created" in err and "Traceback" not in err and "simulate" not in err


@pytest.mark.slow
def test_every_practice_recording_reruns_from_the_cli(tmp_path, shared_dir):
    for src in sorted((shared_dir / "practice").glob("practice_*.csv")):
        out = tmp_path / src.name
        assert main(["simulate", "--like", str(src), "--out", str(out)]) == 0
        assert read_recording(out).n_samples == read_recording(src).n_samples
