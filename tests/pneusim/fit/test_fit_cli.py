"""``pneusim fit`` from the command line: outputs, and one clear sentence for every user mistake."""

import json

import numpy as np
import pytest

from pneusim.cli import main
from pneusim.experiment import standard_experiment
from pneusim.recording import Recording, write_recording
from pneusim.simulate import simulate


@pytest.fixture(scope="module")
def recording_file(tmp_path_factory, rig2):
    exp = standard_experiment(rig2, "pulses", 20.0, "open", seed=5)
    path = tmp_path_factory.mktemp("fit") / "run.csv"
    write_recording(simulate(rig2, exp, seed=6).recording, path)
    return path


@pytest.mark.slow
def test_fit_writes_json_and_report(recording_file, tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert main(["fit", str(recording_file), "--json", str(out), "--report", str(tmp_path / "report")]) == 0
    data = json.loads(out.read_text())
    assert data["rig"] == "paper2-enfield" and data["validation"]["fit_percent"] > 99.0
    assert (tmp_path / "report" / "fit.png").stat().st_size > 10_000
    text = (tmp_path / "report" / "report.md").read_text()
    assert "moving_mass_kg" in text and "Validation fit" in text
    assert "validation" in capsys.readouterr().out


def _error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


def test_unknown_free_parameter_is_refused(recording_file, capsys):
    err = _error(capsys, ["fit", str(recording_file), "--free", "piston_colour"])
    assert "piston_colour" in err and "friction" in err


def test_effect_parameter_without_the_effect_is_refused(recording_file, capsys):
    err = _error(capsys, ["fit", str(recording_file), "--free", "valve_deadband.deadband_V"])
    assert "--effect valve_deadband" in err


def test_wrong_rig_is_refused(recording_file, capsys):
    err = _error(capsys, ["fit", str(recording_file), "--rig", "paper1-mre"])
    assert "stroke" in err and "paper1-mre" in err and str(recording_file) in err


def test_recording_that_does_not_move_is_refused(tmp_path, rig2, capsys):
    n = 1000
    rng = np.random.default_rng(0)
    rec = Recording(time_s=np.arange(n) * 0.01, valve_cmd_V=np.full(n, 5.0),
                    position_m=0.15 + 6e-5 * rng.standard_normal(n),
                    metadata={"sample_time_s": "0.01", "rig": "paper2-enfield", "loop": "open"})
    path = tmp_path / "still.csv"
    write_recording(rec, path)
    err = _error(capsys, ["fit", str(path)])
    assert "moves only" in err and "excite" in err


def test_transport_delay_is_not_fitted_by_gradient(recording_file, capsys):
    err = _error(capsys, ["fit", str(recording_file), "--effect", "transport_delay:delay_s=0.02",
                          "--free", "transport_delay.delay_s"])
    assert "transport_delay.delay_s" in err and "delay_s=VALUE" in err
