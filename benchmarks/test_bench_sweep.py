"""Sweep throughput (runs per second) locally with 1 and 2 worker processes and through Dask.

Each benchmark runs the 50-run tiny sweep of ``tests/scenarios/data/tiny-sweep.toml``
(2 s open-loop simulations + ARX + RLS, one run that raises) into a fresh
directory; ``extra_info["runs_per_s"]`` is the throughput, worker start-up included.

    pytest benchmarks/test_bench_sweep.py --benchmark-only
"""

from pathlib import Path

import pytest

from pneusim.scenario.sweep import load_sweep, run_sweep

SWEEP = Path(__file__).resolve().parents[1] / "tests" / "scenarios" / "data" / "tiny-sweep.toml"


@pytest.mark.parametrize("mode", ["local-1", "local-2", "dask-local-2"])
def test_sweep_throughput(benchmark, tmp_path, mode):
    sweep = load_sweep(SWEEP)
    counter = iter(range(1000))

    def once():
        out = tmp_path / f"run{next(counter)}"
        if mode.startswith("dask"):
            return run_sweep(sweep, out, workers=2, dask="local", progress=False)
        return run_sweep(sweep, out, workers=int(mode[-1]), progress=False)

    info = benchmark.pedantic(once, rounds=2, iterations=1)
    assert info["n_runs"] == 50 and info["n_failed"] == 1
    benchmark.extra_info["runs"] = info["n_runs"]
    benchmark.extra_info["runs_per_s"] = info["n_runs"] / benchmark.stats.stats.mean
