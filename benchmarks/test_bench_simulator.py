"""Simulator speed: CVODE against SciPy BDF and LSODA and CasADi's own CVODES, same model, same run.

CVODE is the SUNDIALS library scikits.odes is built on, created and driven from C through
scikits.odes' Cython declarations (serial N_Vector, dense matrix, dense direct solver), with the
CasADi-generated rhs and Jacobian as its C callbacks and the sample loop in C
(``pneusim/solver/_cvode_compiled.pyx``).

Run with ``bash scripts/bench.sh`` (or ``pytest benchmarks/test_bench_simulator.py --benchmark-only -s``).

Cases: an 80 s closed-loop paper-2 run (multisine) and a 20 s closed-loop paper-1 run
(pulses), both with the sensor noise off.

* ``test_cvode_real_time``: the rigs as shipped (16-bit position converter in the loop):
  the real-time factor of :func:`simulate` with the default CVODE backend, and beside it in the
  same run CVODE with SUNDIALS' own serial vector, dense matrix and dense solver
  (``cvode-sundials``) instead of ``pneusim/solver/small_vector.h``'s and ``small_dense.h``'s,
  which compute the same doubles (asserted).
* ``test_simulator_speed``: the same runs with the position converter off, so that the
  position error against a tight reference is the solver's own (with the converter in
  the loop, a difference far below one code flips a code now and then and the closed
  loop goes its own way, see ``test_cvode_real_time``'s printout).  CVODE, SciPy BDF
  and SciPy LSODA, all on the same CasADi model at rtol 1e-6 with the same absolute
  tolerances.  The reference is CVODE at rtol 1e-10 (its own error is estimated
  against rtol 1e-11 and printed; ``tests/pneusim/solver/test_solver.py`` checks CVODE against
  SciPy Radau at tight tolerance).
* ``test_equal_accuracy``: CVODE at rtol 1e-7 and 1e-8 too; each SciPy peer's time is
  divided by the time of the fastest CVODE run whose error is no larger than the
  peer's, which is the speed ratio at equal (or better) accuracy.
* ``test_restart_policies``: what happens at the input change at every sample boundary
  (``POLICIES`` in ``_cvode_compiled.pyx``): restart (the default), restart reusing the
  previous first step, or keep the BDF history across the kink; steps, rhs and Jacobian
  evaluations per sample, error against the reference and time against the default.
* ``test_casadi_own_cvodes``: CasADi's own SUNDIALS integrator (``cvodes`` in a
  ``mapaccum`` over the samples) on the 80 s paper-2 closed loop and an 80 s open loop,
  same tolerances (states scaled so that CasADi's scalar abstol is ours).

Speed is only reported (``extra_info``, the printout and ``docs/results/simulator.md`` with the
commit, machine, date and command), never asserted; the asserts check that every backend is
in the same accuracy class.  The printout sets the numbers beside the targets: at least 500x
real time for the 80 s closed-loop paper-2 run, at least 20x faster than SciPy BDF at equal
accuracy.
"""

import time

import numpy as np
import pytest

from pneusim.experiment import standard_experiment
from pneusim.rig import load_rig
from pneusim.simulate import simulate
from pneusim.solver.backends import state_scales
from results_file import write_results

CASES = {
    "paper2-closed-80s": ("paper2-enfield", "multisine", 80.0),
    "paper1-closed-20s": ("paper1-mre", "pulses", 20.0),
}
PEERS = ("scipy-bdf", "scipy-lsoda")
RTOL = 1e-6
LADDER = (1e-7, 1e-8)
TARGET_REAL_TIME = {"paper2-closed-80s": 500.0, "paper1-closed-20s": 200.0}  # targets, printed, not asserted
TARGET_VS_BDF = 20.0
RESULTS = {}  # (case, backend, rtol) -> (best wall time s, max position error m)
AS_SHIPPED = {}  # case -> (best s, real-time factor, steps a sample, cvode-sundials real-time factor)
EQUAL_ACCURACY = {}  # (case, peer) -> CVODE's speed-up at equal or better accuracy


@pytest.fixture(scope="module", autouse=True)
def results_table():
    """After the module: the measured speeds in one file, ``docs/results/simulator.md``."""
    yield
    lines = []
    if AS_SHIPPED:
        lines += ["The rigs as shipped (position converter in the loop), sensor noise off, CVODE rtol 1e-6.", "",
                  "| run | time | real time | steps a sample | backend `cvode-sundials` (same doubles) |",
                  "|---|---|---|---|---|"]
        lines += [f"| {case} | {best:.3f} s | **{rt:.0f}x** | {steps:.1f} | {peer:.0f}x real time |"
                  for case, (best, rt, steps, peer) in AS_SHIPPED.items()]
    if RESULTS:
        lines += ["", "Position converter off, against a CVODE reference at rtol 1e-10.", "",
                  "| run | backend | rtol | time | largest position error |", "|---|---|---|---|---|"]
        lines += [f"| {case} | {backend} | {rtol:g} | {best:.3f} s | {error:.1e} m |"
                  for (case, backend, rtol), (best, error) in sorted(RESULTS.items())]
    if EQUAL_ACCURACY:
        lines += ["", "| run | CVODE faster than, at equal or better accuracy |", "|---|---|"]
        lines += [f"| {case} | {peer}: {ratio:.0f}x |" for (case, peer), ratio in EQUAL_ACCURACY.items()]
    if lines:
        write_results("simulator", "Simulator speed", "\n".join(lines))


def _case(name, converter=True, loop="closed", kind=None):
    rig_name, default_kind, duration = CASES[name]
    rig = load_rig(rig_name)
    if not converter:
        rig = rig.with_params({"position_adc_bits": 0})
    return rig, standard_experiment(rig, kind or default_kind, duration, loop, seed=1), duration


_REFERENCE = {}


def _load():
    """The 1-minute load average (the machine may be shared: ratios in one run are what count)."""
    import os

    return f"{os.getloadavg()[0]:.1f}"


def _reference(name, converter=False):
    """Position of CVODE at rtol 1e-10, and its distance to rtol 1e-11 (the reference's own error)."""
    key = (name, converter)
    if key not in _REFERENCE:
        rig, exp, _ = _case(name, converter)
        ref = simulate(rig, exp, noise_scale=0, rtol=1e-10)
        tighter = simulate(rig, exp, noise_scale=0, rtol=1e-11).state("position_m")
        _REFERENCE[key] = (ref, float(np.max(np.abs(ref.state("position_m") - tighter))))
    return _REFERENCE[key]


def _timed(fn, rounds):
    runs = []
    for _ in range(rounds):
        started = time.perf_counter()
        out = fn()
        runs.append((time.perf_counter() - started, out))
    return min(t for t, _ in runs), runs[-1][1]


@pytest.mark.parametrize("case", list(CASES))
def test_cvode_real_time(benchmark, case):
    rig, exp, duration = _case(case, converter=True)
    runs = []

    def run():
        started = time.perf_counter()
        sim = simulate(rig, exp, noise_scale=0)
        runs.append((time.perf_counter() - started, sim))

    benchmark.pedantic(run, rounds=7, iterations=1, warmup_rounds=1)
    best = min(t for t, _ in runs)
    sim = runs[-1][1]
    # the peer in the same run: CVODE with SUNDIALS' own vector, matrix and linear solver instead of
    # small_vector.h's and small_dense.h's (the same doubles: checked here and in tests/pneusim/solver/test_solver.py)
    peer_best, peer = _timed(lambda: simulate(rig, exp, noise_scale=0, backend="cvode-sundials"), 7)
    assert np.array_equal(peer.states, sim.states)
    ref, _ = _reference(case, converter=True)
    error = float(np.max(np.abs(sim.state("position_m") - ref.state("position_m"))))
    stats = sim.solver_stats
    n = exp.n_samples + int(round(exp.warmup_s / exp.sample_time_s))
    AS_SHIPPED[case] = (best, duration / best, stats["steps"] / n, duration / peer_best)
    benchmark.extra_info.update({"real_time_factor": duration / best, "max_position_error_m": error,
                                 "steps_per_sample": stats["steps"] / n,
                                 "real_time_factor_sundials_algebra": duration / peer_best,
                                 "speedup_over_sundials_algebra": peer_best / best})
    print(f"\n{case} as shipped (converter in the loop), cvode rtol {RTOL:g}, load {_load()}: {best:.3f} s, "
          f"{duration / best:.0f}x real time; {stats['steps'] / n:.1f} steps and "
          f"{stats['rhs_evaluations'] / n:.1f} rhs evaluations a sample; position vs rtol 1e-10 "
          f"{error:.1e} m (converter codes flipped by the tolerance, not solver error alone)"
          + (f"; target >= {TARGET_REAL_TIME[case]:.0f}x real time: "
             f"{'met' if duration / best >= TARGET_REAL_TIME[case] else 'not met'}"
             if case in TARGET_REAL_TIME else "")
          + f"\n  with SUNDIALS' own serial vector, dense matrix and solver (same results to the last bit): "
            f"{peer_best:.3f} s, {duration / peer_best:.0f}x real time; small_vector.h and small_dense.h are "
            f"{peer_best / best:.2f}x faster")
    assert error < 1e-3


@pytest.mark.parametrize("backend", ("cvode",) + PEERS)
@pytest.mark.parametrize("case", list(CASES))
def test_simulator_speed(benchmark, case, backend):
    rig, exp, duration = _case(case, converter=False)
    ref, ref_error = _reference(case)
    runs = []

    def run():
        started = time.perf_counter()
        sim = simulate(rig, exp, noise_scale=0, rtol=RTOL, backend=backend)
        runs.append((time.perf_counter() - started, sim))

    benchmark.pedantic(run, rounds=5 if backend == "cvode" else 1, iterations=1,
                       warmup_rounds=1 if backend == "cvode" else 0)
    best = min(t for t, _ in runs)
    error = float(np.max(np.abs(runs[-1][1].state("position_m") - ref.state("position_m"))))
    benchmark.extra_info.update({"real_time_factor": duration / best, "max_position_error_m": error,
                                 "reference_error_m": ref_error})
    RESULTS[(case, backend, RTOL)] = (best, error)
    line = (f"{case} converter off, {backend} rtol {RTOL:g}: {best:.3f} s, {duration / best:.1f}x real time, "
            f"max position error {error:.1e} m (reference's own {ref_error:.0e} m)")
    if backend != "cvode" and (case, "cvode", RTOL) in RESULTS:
        ratio = best / RESULTS[(case, "cvode", RTOL)][0]
        benchmark.extra_info["cvode_speedup_same_rtol"] = ratio
        line += f" -> CVODE at the same rtol is {ratio:.0f}x faster"
    print("\n" + line)
    assert error < 1e-3  # same accuracy class: every backend at rtol 1e-6 stays within 1 mm


@pytest.mark.parametrize("case", list(CASES))
def test_equal_accuracy(benchmark, case):
    rig, exp, duration = _case(case, converter=False)
    ref, _ = _reference(case)

    def ladder():
        for rtol in LADDER:
            best, sim = _timed(lambda: simulate(rig, exp, noise_scale=0, rtol=rtol), 3)
            error = float(np.max(np.abs(sim.state("position_m") - ref.state("position_m"))))
            RESULTS[(case, "cvode", rtol)] = (best, error)

    benchmark.pedantic(ladder, rounds=1, iterations=1)
    lines = [f"\n{case} converter off, CVODE: " + ", ".join(
        f"rtol {r:g}: {RESULTS[(case, 'cvode', r)][0]:.3f} s, error {RESULTS[(case, 'cvode', r)][1]:.1e} m"
        for r in (RTOL,) + LADDER if (case, "cvode", r) in RESULTS)]
    for peer in PEERS:
        if (case, peer, RTOL) not in RESULTS:
            continue
        t_peer, e_peer = RESULTS[(case, peer, RTOL)]
        matching = [r for r in (RTOL,) + LADDER if (case, "cvode", r) in RESULTS
                    and RESULTS[(case, "cvode", r)][1] <= e_peer]
        if not matching:
            lines.append(f"  {peer} (error {e_peer:.1e} m): no CVODE run in the ladder is as accurate")
            continue
        rtol = min(matching, key=lambda r: RESULTS[(case, "cvode", r)][0])
        t_cv, e_cv = RESULTS[(case, "cvode", rtol)]
        ratio = t_peer / t_cv
        benchmark.extra_info[f"cvode_speedup_equal_accuracy_vs_{peer}"] = ratio
        EQUAL_ACCURACY[(case, peer)] = ratio
        lines.append(f"  vs {peer} (rtol {RTOL:g}, error {e_peer:.1e} m, {t_peer:.1f} s): CVODE at rtol "
                     f"{rtol:g} (error {e_cv:.1e} m, {t_cv:.3f} s) is {ratio:.0f}x faster at equal "
                     f"or better accuracy" + (f" (target >= {TARGET_VS_BDF:.0f}x: "
                                               f"{'met' if ratio >= TARGET_VS_BDF else 'not met'})"
                                               if peer == "scipy-bdf" else ""))
    print("\n".join(lines))
    assert all(RESULTS[(case, "cvode", r)][1] < 1e-3 for r in LADDER)


def _casadi_loop(rig, exp, x0, rtol, closed):
    """The whole run inside CasADi: its own CVODES per sample, one ``mapaccum`` over the samples."""
    import casadi as ca

    from pneusim.model import ActuatorModel

    model = ActuatorModel()
    params = ca.DM(model.param_vector(rig))
    scales = state_scales(model, rig.stroke_m)
    # states divided by our atol scales, so that CasADi's scalar abstol (= rtol) is our atol vector
    z = ca.SX.sym("z", len(scales))
    ode = ca.substitute(model.xdot_sym, model.x_sym, z * scales) / scales
    dae = {"x": z, "p": ca.vertcat(model.u_sym, model.p_sym), "ode": ode}
    step_fn = ca.integrator("F", "cvodes", dae, 0.0, rig.sample_time_s,
                            {"reltol": rtol, "abstol": rtol, "max_num_steps": 100000})
    x = ca.MX.sym("x", len(scales))
    ref = ca.MX.sym("r")
    if closed:  # noise off, converter off: the controller reads the true position
        ctrl = exp.controller
        u = ca.fmin(ca.fmax(ctrl.u0_V + ctrl.kp_V_per_m * (ref - x[0]), ctrl.u_min_V), ctrl.u_max_V)
    else:
        u = ref
    step = ca.Function("step", [x, ref], [step_fn(x0=x / scales, p=ca.vertcat(u, params))["xf"] * scales])
    run = step.mapaccum("run", exp.n_samples)
    signal = exp.signal.reshape(1, -1)
    return lambda: np.asarray(run(x0, signal))


@pytest.mark.parametrize("loop", ("closed", "open"))
def test_casadi_own_cvodes(benchmark, loop):
    """CasADi's own SUNDIALS integrator (offered as a backend only where it is faster: it is not)."""
    case = "paper2-closed-80s"
    kind = None if loop == "closed" else "multisine"
    rig, exp, duration = _case(case, converter=False, loop=loop, kind=kind)
    ours = lambda: simulate(rig, exp, noise_scale=0, rtol=RTOL)  # noqa: E731
    reference = simulate(rig, exp, noise_scale=0, rtol=1e-10)
    run = _casadi_loop(rig, exp, reference.states[0], RTOL, loop == "closed")
    out = benchmark.pedantic(run, rounds=3, iterations=1, warmup_rounds=1)
    t_casadi = benchmark.stats.stats.min
    t_ours, sim = _timed(ours, 5)
    positions = np.concatenate([[reference.states[0, 0]], out[0, :-1]])
    e_casadi = float(np.max(np.abs(positions - reference.state("position_m"))))
    e_ours = float(np.max(np.abs(sim.state("position_m") - reference.state("position_m"))))
    ratio = t_casadi / t_ours
    benchmark.extra_info.update({"real_time_factor": duration / t_casadi, "max_position_error_m": e_casadi,
                                 "cvode_backend_speedup": ratio})
    print(f"\n{case.replace('closed', loop)} converter off, rtol {RTOL:g}: casadi cvodes (mapaccum) "
          f"{t_casadi:.3f} s ({duration / t_casadi:.0f}x real time, error {e_casadi:.1e} m); pneusim cvode "
          f"{t_ours:.3f} s incl. {exp.warmup_s:g} s warm-up ({duration / t_ours:.0f}x, error {e_ours:.1e} m): "
          f"{ratio:.1f}x faster")
    assert e_casadi < 1e-3 and e_ours < 1e-3


@pytest.mark.parametrize("case", list(CASES))
def test_restart_policies(benchmark, case):
    """Steps and evaluations per sample of each policy at the input change, and their cost."""
    from pneusim.plant import SimulatedPlant
    from pneusim.solver._cvode_compiled import POLICIES

    rig, exp, duration = _case(case, converter=False)
    ref, _ = _reference(case)
    n = exp.n_samples + int(round(exp.warmup_s / exp.sample_time_s))
    original = SimulatedPlant.__init__
    rows = {}

    def run_all():
        for name, policy in POLICIES.items():
            def init(self, *args, **kwargs):
                original(self, *args, **kwargs)
                self.solver._integrator.restart = policy
            SimulatedPlant.__init__ = init
            try:
                best, sim = _timed(lambda: simulate(rig, exp, noise_scale=0, rtol=RTOL), 3)
            finally:
                SimulatedPlant.__init__ = original
            error = float(np.max(np.abs(sim.state("position_m") - ref.state("position_m"))))
            rows[name] = (best, error, sim.solver_stats)

    benchmark.pedantic(run_all, rounds=1, iterations=1)
    t_default = rows["reinit"][0]
    lines = [f"\n{case} converter off, rtol {RTOL:g}, load {_load()}: the input change at each sample"]
    for name, (best, error, stats) in rows.items():
        per = {k: stats[k] / n for k in ("steps", "rhs_evaluations", "jacobian_evaluations", "error_test_failures")}
        benchmark.extra_info[name] = {"time_s": best, "error_m": error, **per}
        lines.append(f"  {name:16s} {per['steps']:5.2f} steps, {per['rhs_evaluations']:5.2f} rhs, "
                     f"{per['jacobian_evaluations']:4.2f} Jacobians, {per['error_test_failures']:4.2f} error-test "
                     f"failures a sample; position error {error:.1e} m; {duration / best:4.0f}x real time "
                     f"({t_default / best:.2f}x the default's speed)")
    print("\n".join(lines))
    assert rows["reinit"][1] < 1e-3
