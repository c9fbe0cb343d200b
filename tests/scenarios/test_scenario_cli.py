"""``pneusim run`` and ``pneusim sweep`` refuse user mistakes with one sentence and exit code 2."""

from pneusim.cli import main


def test_run_bad_key_exits_2(tmp_path, scenarios_dir, capsys):
    rc = main(["run", str(scenarios_dir / "paper2-multisine.toml"), "--out", str(tmp_path),
               "--set", "experiment.loop=sideways"])
    err = capsys.readouterr().err
    assert rc == 2 and "experiment.loop" in err and "expected one of open, closed" in err


def test_run_missing_file_exits_2(tmp_path, capsys):
    rc = main(["run", str(tmp_path / "nope.toml")])
    assert rc == 2 and "scenario file not found" in capsys.readouterr().err


def test_sweep_missing_scenario_key_exits_2(tmp_path, capsys):
    p = tmp_path / "sw.toml"
    p.write_text("[sweep]\nname = 'x'\n")
    rc = main(["sweep", str(p), "--out", str(tmp_path / "o")])
    assert rc == 2 and "sweep.scenario" in capsys.readouterr().err


def test_run_generic_tiny_scenario(tmp_path, data_dir):
    assert main(["run", str(data_dir / "tiny-open-loop.toml"), "--out", str(tmp_path), "--no-progress"]) == 0
    assert (tmp_path / "report.html").exists() and (tmp_path / "metrics.json").exists()
