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


def _casadi_closed_loop(rig, exp, x0, rtol):
    """The same closed loop entirely inside CasADi: its own CVODES, one ``mapaccum`` over the samples."""
    import casadi as ca

    from pneusim.model import ActuatorModel

    model = ActuatorModel()
    params = ca.DM(model.param_vector(rig))
    dae = {"x": model.x_sym, "p": ca.vertcat(model.u_sym, model.p_sym), "ode": model.xdot_sym}
    scales = np.array([rig.stroke_m, 1.0, 1e5, 1e5])
    step_fn = ca.integrator("F", "cvodes", dae, 0.0, rig.sample_time_s,
                            {"reltol": rtol, "abstol": float(rtol * scales.min()), "max_num_steps": 100000})
    ctrl = exp.controller
    x = ca.MX.sym("x", 4)
    ref = ca.MX.sym("r")
    quantum = rig.stroke_m / (2 ** 16 - 1)
    measured = ca.floor(ca.fmin(ca.fmax(x[0], 0.0), rig.stroke_m) / quantum + 0.5) * quantum
    u = ca.fmin(ca.fmax(ctrl.u0_V + ctrl.kp_V_per_m * (ref - measured), ctrl.u_min_V), ctrl.u_max_V)
    step = ca.Function("step", [x, ref], [step_fn(x0=x, p=ca.vertcat(u, params))["xf"]])
    run = step.mapaccum("run", exp.n_samples)
    return lambda: np.asarray(run(x0, exp.signal.reshape(1, -1)))


def test_casadi_own_cvodes_for_comparison(benchmark):
    """CasADi's own SUNDIALS integrator on the same closed loop (offered only where it is faster)."""
    case = "paper2-closed-80s"
    rig, exp, duration = _case(case)
    reference_run = simulate(rig, exp, noise_scale=0, rtol=1e-10)
    run = _casadi_closed_loop(rig, exp, reference_run.states[0], 1e-6)
    out = benchmark.pedantic(run, rounds=2, iterations=1)
    positions = np.concatenate([[reference_run.states[0, 0]], out[0, :-1]])
    error = float(np.max(np.abs(positions - reference_run.state("position_m"))))
    best = benchmark.stats.stats.min
    line = f"{case} casadi-cvodes (mapaccum): {best:.3f} s, {duration / best:.0f}x real time, max error {error:.2e} m"
    if (case, "cvode") in RESULTS:
        line += f"; scikits.odes CVODE backend is {best / RESULTS[(case, 'cvode')][0]:.1f}x faster"
    print("\n" + line)
    assert error < 1e-3
