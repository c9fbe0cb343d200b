"""``pneusim run`` and ``pneusim sweep`` refuse user mistakes with one sentence naming the file, the key and
what was expected, and exit code 2; no traceback reaches the user."""

import subprocess
import sys

import pytest

from pneusim.cli import main

HEAD = """[scenario]
name = "bad"
[rig]
name = "paper2-enfield"
{rig}
[experiment]
loop = "{loop}"
duration_s = {duration}
{experiment}
[[identifiers]]
name = "a"
{ident}
"""
SIGNAL = 'signal = { kind = "multisine", components = [[0.5, 0.5]], offset = 5.0 }'


def _file(tmp_path, rig="", loop="open", duration=2.0, experiment=SIGNAL, ident='kind = "arx"\norders = [2, 2, 1]',
          extra=""):
    p = tmp_path / "bad.toml"
    p.write_text(HEAD.format(rig=rig, loop=loop, duration=duration, experiment=experiment, ident=ident) + extra)
    return p


@pytest.mark.parametrize("kwargs, key, expected", [
    ({"rig": 'overrides = { nosuch_param = 3.0 }'}, "rig.overrides.nosuch_param", "unknown parameter"),
    ({"rig": 'overrides = { moving_mass_kg = -1.0 }'}, "rig.overrides.moving_mass_kg", "must be positive"),
    ({"rig": 'effects = ["nosuch:x=1"]'}, "rig.effects[0]", "expected one of"),
    ({"rig": 'effects = ["valve_deadband:deadband_V=abc"]'}, "rig.effects[0]", "must be a number"),
    ({"duration": 0.1}, "experiment.duration_s", "at least 50 samples"),
    ({"duration": 1e12}, "experiment.duration_s", "at most 10000000 samples"),
    ({"experiment": 'signal = { kind = "multisine", unit = "m", components = [[0.01, 0.5]] }'},
     "experiment.signal.unit", "expected 'native'"),
    ({"experiment": 'signal = { kind = "multisine", width_s = [0.1, 0.2], components = [[0.5, 0.5]] }'},
     "experiment.signal.width_s", "for kind = 'multisine'"),
    ({"experiment": 'initial_position_m = 0.5\n' + SIGNAL}, "experiment.initial_position_m", "[0, 0.3048]"),
    ({"loop": "closed", "experiment": 'controller = { kp = 3.0 }\n' + SIGNAL}, "experiment.controller.kp",
     "unknown key"),
    ({"extra": '[[variants]]\nname = "v"\nexperiment = { colour = 1 }\n'}, "variants[0].experiment.colour",
     "unknown key"),
    ({"ident": 'kind = "published_z"\nnum = ["a"]\nden = [1.0, 0.5]'}, "identifiers[0].num", "list of numbers"),
    ({"ident": 'kind = "published_z"\nnum = [1.0]\nden = [0.0, 1.0]'}, "identifiers[0].den", "non-zero leading"),
    ({"ident": 'kind = "tf"\nnp = 2\nnz = 5'}, "identifiers[0].nz", "[0, np = 2]"),
    ({"ident": 'kind = "ss"\nnx = 0'}, "identifiers[0].nx", "positive integer"),
    ({"ident": 'kind = "rls"\norder = 2\nhorizons = [0]'}, "identifiers[0].horizons", "positive integers"),
    ({"ident": 'kind = "arx"\norders = [2, 2, 1]\nnx = 3'}, "identifiers[0].nx", "for kind = 'arx'"),
    ({"ident": 'kind = "published_s"\nnum = [1.0]\nden = [1.0, 1.0]\ntime_units = ["min"]'},
     "identifiers[0].time_units", "expected one of s, ms, sample"),
])
def test_bad_scenario_file_names_file_key_and_expectation(tmp_path, capsys, kwargs, key, expected):
    path = _file(tmp_path, **kwargs)
    rc = main(["run", str(path), "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert str(path) in err and f"field '{key}'" in err and expected in err, err
    assert "Traceback" not in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()          # refused before anything ran


@pytest.mark.slow
def test_unknown_rig_through_the_installed_command(tmp_path):
    path = _file(tmp_path)
    path.write_text(path.read_text().replace('name = "paper2-enfield"', 'name = "nosuchrig"'))
    proc = subprocess.run([sys.executable, "-m", "pneusim.cli", "run", str(path)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert str(path) in proc.stderr and "field 'rig.name'" in proc.stderr and "paper1-mre" in proc.stderr


def test_run_bad_set_exits_2(tmp_path, scenarios_dir, capsys):
    rc = main(["run", str(scenarios_dir / "paper2-multisine.toml"), "--out", str(tmp_path),
               "--set", "experiment.loop=sideways"])
    err = capsys.readouterr().err
    assert rc == 2 and "paper2-multisine.toml --set" in err and "experiment.loop" in err
    assert "expected one of open, closed" in err
    rc = main(["run", str(scenarios_dir / "paper2-multisine.toml"), "--set", "identifiers.9.order=3"])
    err = capsys.readouterr().err
    assert rc == 2 and "identifiers.9.order" in err and "no list item '9'" in err


def test_run_missing_file_exits_2(tmp_path, capsys):
    rc = main(["run", str(tmp_path / "nope.toml")])
    assert rc == 2 and "scenario file not found" in capsys.readouterr().err


@pytest.mark.parametrize("text, key", [
    ("[sweep]\nname = 'x'\n", "sweep.scenario"),
    ("[sweep]\nscenario = 'SCEN'\n[grid]\n'experiment.colour' = [1, 2]\n", "experiment.colour"),
    ("[sweep]\nscenario = 'SCEN'\n[random]\nn = 3\n'experiment.noise_scale' = { low = 2.0, high = 1.0 }\n",
     "random.experiment.noise_scale"),
    ("[sweep]\nscenario = 'SCEN'\n[[points]]\n'rig.overrides.nosuch' = 1.0\n", "rig.overrides.nosuch"),
    ("[sweep]\nscenario = 'SCEN'\nseeds = []\n", "sweep.seeds"),
])
def test_bad_sweep_file_exits_2(tmp_path, data_dir, capsys, text, key):
    p = tmp_path / "sw.toml"
    p.write_text(text.replace("SCEN", str(data_dir / "tiny-open-loop.toml")))
    rc = main(["sweep", str(p), "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and key in err and "Traceback" not in err, err


@pytest.mark.slow
def test_run_generic_tiny_scenario(tmp_path, data_dir):
    assert main(["run", str(data_dir / "tiny-open-loop.toml"), "--out", str(tmp_path), "--no-progress"]) == 0
    assert (tmp_path / "report.html").exists() and (tmp_path / "metrics.json").exists()


@pytest.mark.parametrize("command", ["run", "sweep"])
def test_help_lists_options_and_examples(command, capsys):
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    out = capsys.readouterr().out
    assert exc.value.code == 0 and "examples:" in out and "--out DIR" in out and "scenarios/README.md" in out
    assert ("--set KEY=VALUE" in out) if command == "run" else ("--dask ADDRESS" in out and "--workers N" in out)
