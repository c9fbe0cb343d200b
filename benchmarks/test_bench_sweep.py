"""Sweep throughput (runs per second): in this process, 1 and 2 local worker processes, and Dask.

Every benchmark runs the 50-run sweep of ``tests/pneusim/scenario/data/tiny-sweep.toml`` (open-loop doublets on
the paper 2 rig, ARX + in-loop RLS, one run that raises) with each run lengthened to 8 s (800 samples),
into a fresh directory, so nothing is skipped.  Modes:

* ``inprocess``: ``--workers 0``, the runs one after the other in this process (the peer of the others);
* ``local-1``, ``local-2``: a ``ProcessPoolExecutor`` of 1 or 2 processes, start-up included;
* ``dask-local-2``: ``--dask local --workers 2``, the LocalCluster's start-up included;
* ``dask-running-2``: a running LocalCluster of 2 loopback workers (``--dask tcp://...``), the steady
  throughput of a cluster that already exists.

``extra_info["runs_per_s"]`` is the throughput and ``extra_info["speedup_vs_local_1"]`` its ratio to
``local-1`` measured in the same session.  Where the time goes is printed beside it: the runs (the
executor's wall time), what follows them (table, Parquet/CSV, plots: drawn one figure per worker with
more than one worker), the CPU time of this process and of the worker processes, and the load average
(the machine may be shared: a busy machine gives the workers less than a core each).  Local workers are
forked after :func:`pneusim.scenario.sweep._warm_up` built the model and its compiled kernels once.
Run with ``-s`` to see the summary table (also written to ``docs/results/sweep.md`` with the commit,
machine, date and command)::

    pytest benchmarks/test_bench_sweep.py --benchmark-only -s
"""

import json
import os
import resource
import time
from pathlib import Path

import pytest

from pneusim.scenario.sweep import load_sweep, run_sweep
from results_file import write_results

SWEEP = Path(__file__).resolve().parents[1] / "tests" / "pneusim" / "scenario" / "data" / "tiny-sweep.toml"
MODES = ["inprocess", "local-1", "local-2", "dask-local-2", "dask-running-2"]
RESULTS: dict[str, float] = {}
PARTS: dict[str, str] = {}


def _cpu(who):
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    sw = load_sweep(SWEEP)
    sw["base"] = {**sw["base"], "experiment.duration_s": 8.0}
    run_sweep({**sw, "random": {}, "points": [{}]}, tmp_path_factory.mktemp("warmup"), workers=0,
              progress=False)                                  # imports and compiled code, once
    yield sw
    if RESULTS:
        base = RESULTS.get("local-1")
        print("\nsweep throughput, 50 runs of 8 s (800 samples) each:")
        lines = ["50 runs of 8 s (800 samples) each.", "", "| mode | runs/s | against local-1 | where the time goes |",
                 "|---|---|---|---|"]
        for mode in MODES:
            if mode in RESULTS:
                ratio = f"{RESULTS[mode] / base:5.2f} x local-1" if base else ""
                print(f"  {mode:15s} {RESULTS[mode]:6.2f} runs/s  {ratio}  {PARTS.get(mode, '')}")
                lines.append(f"| {mode} | {RESULTS[mode]:.2f} | {ratio.replace(' x local-1', 'x').strip() or '-'} | "
                             f"{PARTS.get(mode, '')} |")
        write_results("sweep", "Sweep throughput", "\n".join(lines))


@pytest.fixture(scope="module")
def running_cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", processes=True,
                                  dashboard_address=None) as cluster:
        yield cluster.scheduler_address


@pytest.mark.parametrize("mode", MODES)
def test_sweep_throughput(benchmark, tmp_path, sweep, request, mode):
    counter = iter(range(1000))
    address = request.getfixturevalue("running_cluster") if mode == "dask-running-2" else None

    parts = []

    def once():
        out = tmp_path / f"run{next(counter)}"
        cpu_self, cpu_children, started = _cpu(resource.RUSAGE_SELF), _cpu(resource.RUSAGE_CHILDREN), time.perf_counter()
        if mode == "inprocess":
            info = run_sweep(sweep, out, workers=0, progress=False)
        elif mode == "dask-local-2":
            info = run_sweep(sweep, out, workers=2, dask="local", progress=False)
        elif mode == "dask-running-2":
            info = run_sweep(sweep, out, dask=address, progress=False)
        else:
            info = run_sweep(sweep, out, workers=int(mode[-1]), progress=False)
        total = time.perf_counter() - started
        per_worker = {}
        for f in (out / "runs").glob("*.json"):
            res = json.loads(f.read_text())
            per_worker[res["worker_pid"]] = per_worker.get(res["worker_pid"], 0.0) + (res.get("run_cpu_s") or 0.0)
        parts.append((total, info["wall_time_s"], _cpu(resource.RUSAGE_SELF) - cpu_self,
                      _cpu(resource.RUSAGE_CHILDREN) - cpu_children, os.getloadavg()[0], sorted(per_worker.values())))
        return info

    info = benchmark.pedantic(once, rounds=2, iterations=1)
    total, runs_s, cpu_self, cpu_workers, load, per_worker = min(parts)
    PARTS[mode] = (f"best {total:.2f} s = runs {runs_s:.2f} s + table and plots {total - runs_s:.2f} s; "
                   f"cpu this process {cpu_self:.2f} s, local workers {cpu_workers:.2f} s (in runs, per worker: "
                   f"{', '.join(f'{c:.2f}' for c in per_worker)} s); load {load:.1f}")
    benchmark.extra_info.update({"runs_wall_s": runs_s, "after_runs_wall_s": total - runs_s,
                                 "cpu_this_process_s": cpu_self, "cpu_local_workers_s": cpu_workers,
                                 "load_average": load})
    assert info["n_runs"] == 50 and info["n_failed"] == 1 and info["n_done_before"] == 0
    RESULTS[mode] = info["n_runs"] / benchmark.stats.stats.mean
    benchmark.extra_info["runs"] = info["n_runs"]
    benchmark.extra_info["runs_per_s"] = RESULTS[mode]
    if "local-1" in RESULTS:
        benchmark.extra_info["speedup_vs_local_1"] = RESULTS[mode] / RESULTS["local-1"]
