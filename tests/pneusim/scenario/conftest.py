"""Shared fixtures of the scenario tests: the two paper scenarios are run once per session
(shortened with --set), through the command line, into temporary directories."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
DATA = Path(__file__).with_name("data")
SCENARIOS = ROOT / "scenarios"


@pytest.fixture
def scenarios_dir():
    return SCENARIOS


@pytest.fixture
def data_dir():
    return DATA


@pytest.fixture(scope="session")
def paper1_run(tmp_path_factory):
    """Paper 1 scenario, 4 s instead of 20 s, run in this process through ``pneusim.cli.main``."""
    from pneusim.cli import main

    out = tmp_path_factory.mktemp("paper1")
    rc = main(["run", str(SCENARIOS / "paper1-online-rls.toml"), "--out", str(out),
               "--set", "experiment.duration_s=4.0", "--no-progress"])
    assert rc == 0
    return out, json.loads((out / "metrics.json").read_text())


@pytest.fixture(scope="session")
def paper2_run(tmp_path_factory):
    """Paper 2 scenario, 20 s instead of 80 s, run as the installed command in a subprocess."""
    out = tmp_path_factory.mktemp("paper2")
    proc = subprocess.run([sys.executable, "-m", "pneusim.cli", "run", str(SCENARIOS / "paper2-multisine.toml"),
                           "--out", str(out), "--set", "experiment.duration_s=20.0", "--no-progress"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    return out, json.loads((out / "metrics.json").read_text())
