"""A 50-run sweep with one failing run: local processes and a real Dask scheduler give the same table;
a restarted sweep skips what is done."""

import json
import os

import pyarrow.parquet as pq
import pytest

from pneusim.cli import main
from pneusim.scenario.sweep import load_sweep, run_sweep

TIMING = ("identifier_time_s", "run_time_s")


def _comparable(table):
    return [{k: v for k, v in row.items() if k not in TIMING} for row in table]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    from pathlib import Path
    return load_sweep(Path(__file__).with_name("data") / "tiny-sweep.toml")


@pytest.fixture(scope="module")
def local_run(sweep, tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep-local")
    info = run_sweep(sweep, out, workers=2, progress=False)
    return out, info


def test_local_sweep_table(local_run):
    out, info = local_run
    assert info["n_runs"] == 50 and info["n_failed"] == 1
    table = info["table"]
    assert len(table) == 49 * 2 + 1
    failed = [r for r in table if r["status"] == "run failed"]
    assert len(failed) == 1 and "moving_mass_kg" in failed[0]["error"]
    assert failed[0]["rig.overrides.moving_mass_kg"] == -1.0
    ok = [r for r in table if r["status"] == "ok"]
    assert {r["identifier"] for r in ok} == {"ARX 2 2 1", "RLS 2"} or {r["identifier"] for r in ok} == {"RLS 2"}
    assert all(r["fit_percent"] is not None for r in ok)
    pq_table = pq.read_table(out / "sweep.parquet").to_pylist()
    assert len(pq_table) == len(table)
    assert (out / "sweep.csv").read_text().count("\n") == len(table) + 1
    assert list(out.glob("summary-*.png"))


def test_dask_sweep_same_table(sweep, local_run, tmp_path):
    from distributed import LocalCluster

    _, local_info = local_run
    with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", processes=True,
                      dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        info = run_sweep(sweep, tmp_path, dask=cluster.scheduler_address, progress=False)
    assert info["n_runs"] == 50 and info["n_failed"] == 1
    assert _comparable(info["table"]) == _comparable(local_info["table"])
    pids = {json.loads(p.read_text())["worker_pid"] for p in (tmp_path / "runs").glob("*.json")}
    assert os.getpid() not in pids and len(pids) == 2


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
    # through the command line: everything is done, nothing runs again
    assert main(["sweep", str(sweep["path"]), "--out", str(tmp_path), "--no-progress", "--workers", "1"]) == 0
    again = pq.read_table(tmp_path / "sweep.parquet").to_pylist()
    assert _comparable(again) == _comparable(local_info["table"])
