"""A 50-run sweep with one failing run: local processes and a real Dask scheduler with its workers (started
here as separate processes, loopback only) give the same table; a restarted sweep skips what is done."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from pneusim.cli import main
from pneusim.scenario.sweep import load_sweep, run_sweep

TIMING = ("identifier_time_s", "run_time_s")
SWEEP = Path(__file__).with_name("data") / "tiny-sweep.toml"


def _comparable(table):
    return [{k: v for k, v in row.items() if k not in TIMING} for row in table]


def _pids(out):
    return {json.loads(p.read_text())["worker_pid"] for p in (out / "runs").glob("*.json")}


@pytest.fixture(scope="module")
def sweep():
    return load_sweep(SWEEP)


@pytest.fixture(scope="module")
def local_run(sweep, tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep-local")
    info = run_sweep(sweep, out, workers=2, progress=False)
    return out, info


@pytest.mark.slow
def test_local_sweep_table(local_run):
    out, info = local_run
    assert info["n_runs"] == 50 and info["n_failed"] == 1
    table = info["table"]
    assert len(table) == 49 * 2 + 1
    failed = [r for r in table if r["status"] == "run failed"]
    assert len(failed) == 1 and "moving_mass_kg" in failed[0]["error"] and "must be positive" in failed[0]["error"]
    assert failed[0]["rig.overrides.moving_mass_kg"] == -1.0
    ok = [r for r in table if r["status"] == "ok"]
    assert {r["identifier"] for r in ok} == {"ARX 2 2 1", "RLS 2"}
    assert all(r["fit_percent"] is not None for r in ok)
    # one column per varied key, the drawn values inside their ranges
    masses = [r["rig.overrides.moving_mass_kg"] for r in ok]
    assert len(set(masses)) == 49 and all(0.6 <= v <= 2.4 for v in masses)
    pq_table = pq.read_table(out / "sweep.parquet").to_pylist()
    assert _comparable(pq_table) == _comparable(table)
    assert (out / "sweep.csv").read_text().count("\n") == len(table) + 1
    assert {p.name for p in out.glob("summary-*.png")} == {"summary-rig.overrides.moving_mass_kg.png",
                                                          "summary-experiment.noise_scale.png"}
    assert len(_pids(out) - {None}) == 2 and os.getpid() not in _pids(out)


@pytest.fixture
def dask_cluster(tmp_path):
    """A Dask scheduler and two worker processes, started as commands on 127.0.0.1 and stopped after."""
    pytest.importorskip("distributed")
    dask = Path(sys.executable).with_name("dask")
    if not dask.exists():
        pytest.skip("the dask command is not installed beside this Python")
    sched_file = tmp_path / "scheduler.json"
    procs = []

    def start(*args):
        procs.append(subprocess.Popen([str(dask), *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      start_new_session=True))

    try:
        start("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(sched_file))
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        start("worker", "--scheduler-file", str(sched_file), "--nworkers", "2", "--nthreads", "1",
              "--host", "127.0.0.1", "--no-dashboard")
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
            worker_hosts = {w.split("://")[1].rsplit(":", 1)[0] for w in client.scheduler_info()["workers"]}
        assert address.startswith("tcp://127.0.0.1:") and worker_hosts == {"127.0.0.1"}
        yield address
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()


@pytest.mark.slow
def test_dask_sweep_same_table(local_run, dask_cluster, tmp_path, capsys):
    _, local_info = local_run
    out = tmp_path / "dask"
    assert main(["sweep", str(SWEEP), "--out", str(out), "--dask", dask_cluster, "--no-progress"]) == 0
    assert "50 runs (0 done before, 1 failed)" in capsys.readouterr().out
    table = pq.read_table(out / "sweep.parquet").to_pylist()
    assert _comparable(table) == _comparable(local_info["table"])
    pids = _pids(out) - {None}
    assert os.getpid() not in pids and len(pids) == 2              # both Dask workers ran runs


@pytest.mark.slow
def test_restart_skips_done_runs(sweep, local_run, tmp_path):
    out, local_info = local_run
    # a crashed sweep: copy 45 of the 50 stored runs, then restart
    (tmp_path / "runs").mkdir()
    done = sorted((out / "runs").glob("*.json"))[:45]
    for f in done:
        (tmp_path / "runs" / f.name).write_text(f.read_text())
    info = run_sweep(sweep, tmp_path, workers=2, progress=False)
    assert info["n_done_before"] == 45
    assert _comparable(info["table"]) == _comparable(local_info["table"])
    # through the command line: everything is done, nothing runs again, same table
    assert main(["sweep", str(sweep["path"]), "--out", str(tmp_path), "--no-progress", "--workers", "1"]) == 0
    again = pq.read_table(tmp_path / "sweep.parquet").to_pylist()
    assert _comparable(again) == _comparable(local_info["table"])
    # --retry-failed runs the failed one again (and it fails again, deterministically)
    info = run_sweep(sweep, tmp_path, workers=0, progress=False, retry_failed=True)
    assert info["n_done_before"] == 49 and info["n_failed"] == 1


@pytest.mark.slow
def test_dask_local_through_the_command_line(tmp_path, capsys):
    """--dask local starts a loopback LocalCluster (here with one worker) for a 5-run sweep."""
    pytest.importorskip("distributed")
    p = tmp_path / "small.toml"
    p.write_text(SWEEP.read_text().replace("n = 49", "n = 4").replace('"tiny-open-loop.toml"',
                                                                       f'"{SWEEP.with_name("tiny-open-loop.toml")}"'))
    assert main(["sweep", str(p), "--out", str(tmp_path / "o"), "--dask", "local", "--workers", "1",
                 "--no-progress"]) == 0
    assert "5 runs (0 done before, 1 failed)" in capsys.readouterr().out
    pids = _pids(tmp_path / "o") - {None}
    assert len(pids) == 1 and os.getpid() not in pids
