"""Physical fit speed: pneusim's fit (multiple shooting, CVODES sensitivities, trust region + IPOPT)
against SciPy's ``least_squares`` with finite-difference gradients on the same simulator.

The recording: the 8000-sample paper-2 closed-loop multisine (10 ms, sensor noise on) of a rig
whose seven default free parameters differ from the data sheet by 20-30 %.  Both start from the
rig file's values.  The SciPy peer re-runs the recording's experiment (controller in the loop, the
way one fits a closed-loop recording without multiple shooting) with ``pneusim.simulate`` and
differentiates it by finite differences.  Each benchmark prints its time, the largest parameter
error and the validation fit; the second prints the speed ratio measured in the same run.

    pytest benchmarks/test_bench_fit.py --benchmark-only -s

The rows measured are written to ``docs/results/fit-speed.md`` with the commit, machine, date and
command (:mod:`results_file`).

A third benchmark fits paper 1's rig (1 ms sampling, 20000 samples, closed loop, both pressures
recorded) with the same factors off its data sheet and prints its time against the 30 s target.
"""

import time

import numpy as np
import pytest
from scipy.optimize import least_squares

from pneusim.experiment import standard_experiment
from pneusim.fit import DEFAULT_FREE, fit_recording
from pneusim.metrics import fit_percent
from pneusim.rig import load_rig
from pneusim.simulate import rerun_recording, simulate
from results_file import write_results

RESULTS = {}
#: ``[(fit, seconds, largest parameter error, validation fit %, note)]`` for the results file
ROWS = []
FACTORS = {"valve_sonic_conductance_m3_per_s_Pa": 0.8, "valve_critical_pressure_ratio": 0.26 / 0.3,
           "friction_static_N": 1.2, "friction_coulomb_N": 0.9, "friction_stribeck_velocity_m_per_s": 1.3,
           "friction_viscous_N_s_per_m": 1.2, "moving_mass_kg": 1.25}


def _closed_loop_case(rig_name, kind, duration_s, pressures):
    """``(data-sheet rig, true parameters, recording)``: the rig with :data:`FACTORS` applied, in closed loop."""
    rig = load_rig(rig_name)
    truth = {k: rig[k] * f for k, f in FACTORS.items()}
    true_rig = rig.with_params(truth)
    experiment = standard_experiment(true_rig, kind, duration_s, "closed", seed=1)
    recording = simulate(true_rig, experiment, seed=2, record_pressures=pressures).recording
    return rig, truth, recording


@pytest.fixture(scope="module", autouse=True)
def results_table():
    """After the module: every fit measured, in one table (``docs/results/fit-speed.md``)."""
    yield
    if not ROWS:
        return
    lines = ["| fit | time | largest parameter error | validation fit | |", "|---|---|---|---|---|"]
    lines += [f"| {name} | {seconds:.2f} s | {100 * error:.2f} % | {validation:.2f} % | {note} |"
              for name, seconds, error, validation, note in ROWS]
    if SENSITIVITY_RUNS:
        lines += ["", "| one evaluation of the pre-fit window with sensitivities (one thread) | median |", "|---|---|"]
        lines += [f"| corrector `{c}` | {1e3 * t:.0f} ms |" for c, (t, _) in SENSITIVITY_RUNS.items()]
    write_results("fit-speed", "Physical fit speed against SciPy's least_squares on the same simulator",
                  "\n".join(lines))


@pytest.fixture(scope="module")
def case():
    return _closed_loop_case("paper2-enfield", "multisine", 80.0, pressures=False)


def _report(name, seconds, estimates, truth, validation):
    error = max(abs(estimates[k] / truth[k] - 1.0) for k in truth)
    RESULTS[name] = (seconds, error)
    line = f"{name}: {seconds:.1f} s, largest parameter error {100 * error:.2f} %, validation fit {validation:.2f} %"
    note = "paper 2, 80 s closed-loop multisine, seven free parameters"
    if name != "pneusim" and "pneusim" in RESULTS:
        ours, our_error = RESULTS["pneusim"]
        line += f" -> pneusim is {seconds / ours:.1f}x faster"
        note = f"pneusim is {seconds / ours:.1f}x faster"
        if error > 2.0 * max(our_error, 0.01):
            # a peer that stops in a local minimum never reaches equal accuracy: the wall-time ratio is
            # then a lower bound of the speed-up at equal accuracy, and saying so is the honest report
            line += (f" in wall time, and the peer stopped at {100 * error:.1f} % error against pneusim's "
                     f"{100 * our_error:.2f} %: at equal accuracy the ratio is unbounded")
    print("\n" + line)
    ROWS.append((name, seconds, error, validation, note))
    return error


def _pneusim_fit(benchmark, recording, rig, **options):
    """One timed :func:`fit_recording` as the benchmark's round: ``(result, seconds)``."""
    out = {}

    def run():
        started = time.perf_counter()
        out["result"] = fit_recording(recording, rig, **options)
        out["seconds"] = time.perf_counter() - started

    benchmark.pedantic(run, rounds=1, iterations=1)
    return out["result"], out["seconds"]


@pytest.mark.benchmark(group="fit")
def test_fit_pneusim(benchmark, case):
    rig, truth, recording = case
    result, seconds = _pneusim_fit(benchmark, recording, rig)
    error = _report("pneusim", seconds, result.estimates, truth, result.fit_percent)
    benchmark.extra_info.update({"seconds": seconds, "largest_error": error,
                                 "validation_fit_percent": result.fit_percent})
    assert error < 0.05


@pytest.mark.benchmark(group="fit")
def test_fit_scipy_least_squares_finite_differences(benchmark, case):
    rig, truth, recording = case
    n = recording.n_samples
    n_est = int(round(0.7 * n))
    estimation = recording.slice(None, recording.time_s[n_est])
    validation = recording.slice(recording.time_s[n_est], None)
    start = np.array([rig[k] for k in DEFAULT_FREE])
    sigma = rig["position_noise_std_m"]

    def rig_of(theta):
        return rig.with_params(dict(zip(DEFAULT_FREE, theta * start)))

    def residuals(theta):
        sim = rerun_recording(rig_of(theta), estimation, noise_scale=0.0)
        return (sim.recording.position_m - estimation.position_m) / sigma

    out = {}

    def run():
        started = time.perf_counter()
        out["fit"] = least_squares(residuals, np.ones(len(start)), bounds=(0.05, 20.0), method="trf",
                                   x_scale=1.0, diff_step=1e-4, max_nfev=400)
        out["seconds"] = time.perf_counter() - started

    benchmark.pedantic(run, rounds=1, iterations=1)
    theta = out["fit"].x
    val = rerun_recording(rig_of(theta), validation, noise_scale=0.0).recording.position_m
    estimates = dict(zip(DEFAULT_FREE, theta * start))
    error = _report("scipy least_squares (finite differences)", out["seconds"], estimates, truth,
                    fit_percent(validation.position_m, val))
    benchmark.extra_info.update({"seconds": out["seconds"], "largest_error": error,
                                 "function_evaluations": int(out["fit"].nfev)})


#: the target for the paper-1 closed-loop fit with pressures, s (printed, not asserted)
PAPER1_TARGET_S = 30.0


@pytest.fixture(scope="module")
def paper1_case():
    """Paper 1's rig (1 ms sampling) in closed loop, 20 s of pulses (20000 samples), both chamber
    pressures recorded, the same factors off the data sheet as the paper-2 case."""
    return _closed_loop_case("paper1-mre", "pulses", 20.0, pressures=True)


@pytest.mark.benchmark(group="fit")
def test_fit_pneusim_paper1_closed_loop_with_pressures(benchmark, paper1_case):
    rig, truth, recording = paper1_case
    result, seconds = _pneusim_fit(benchmark, recording, rig, quiet=True)
    error = max(abs(result.estimates[k] / truth[k] - 1.0) for k in truth)
    line = (f"paper 1, closed-loop pulses with pressures ({recording.n_samples} samples): {seconds:.1f} s, "
            f"largest parameter error {100 * error:.2f} %, normalised residual {result.normalised_residual:.3f}, "
            f"validation fit {result.fit_percent:.2f} %; target < {PAPER1_TARGET_S:.0f} s: "
            f"{'met' if seconds < PAPER1_TARGET_S else 'not met'}")
    if "pneusim" in RESULTS:
        line += f"; {seconds / RESULTS['pneusim'][0]:.1f}x the paper-2 fit's time in this run"
    print("\n" + line)
    ROWS.append(("pneusim, paper 1", seconds, error, result.fit_percent,
                 f"20 s closed-loop pulses with pressures ({recording.n_samples} samples), target "
                 f"{PAPER1_TARGET_S:.0f} s; normalised residual {result.normalised_residual:.3f}"))
    benchmark.extra_info.update({"seconds": seconds, "largest_error": error,
                                 "normalised_residual": result.normalised_residual})
    assert result.converged_to_noise and error < 0.05


#: ``{corrector: (median seconds, the evaluation's (x, S) per segment)}`` of :func:`test_sensitivity_evaluation`
SENSITIVITY_RUNS = {}


@pytest.mark.benchmark(group="fit-sensitivities")
@pytest.mark.parametrize("corrector", ["staggered", "augmented"])
def test_sensitivity_evaluation(benchmark, case, corrector):
    """One evaluation of the paper-2 fit's pre-fit window with sensitivities (its 40 segments of 50
    samples, at the data sheet's values, one thread) by each corrector of
    :class:`pneusim.solver.sensitivity.SensitivitySimulator`; the second prints the ratio and the
    largest difference of the two corrector's position sensitivities (share of each column's range)."""
    from pneusim.fit.initial import initial_starts
    from pneusim.fit.setup import FitSetup
    from pneusim.solver.sensitivity import SensitivitySimulator

    rig, truth, recording = case
    setup = FitSetup(recording, rig, (), None, None, None, None, 50)
    pb, _, _ = setup.problem(2000, 1e-6, 1)
    theta = setup.theta_start
    starts = initial_starts(pb, theta, recording, 2000)
    pb.close()
    sim = SensitivitySimulator(pb.model, pb.free, pb.params_of(theta), setup.scales, rig.stroke_m, 1e-6,
                               pb.x_scale, corrector=corrector)
    assert sim.corrector == corrector
    segments = [(pb.data.time_s[a], starts[j], pb.schedules[j], b - a + 1)
                for j, (a, b) in enumerate(zip(pb.starts, pb.stops))]

    def evaluate():
        return [sim.run(t0, x0, schedule, n_out, True) for t0, x0, schedule, n_out in segments]

    out = benchmark.pedantic(evaluate, rounds=5, iterations=1, warmup_rounds=1)
    SENSITIVITY_RUNS[corrector] = (benchmark.stats.stats.median, out)
    if corrector == "augmented" and "staggered" in SENSITIVITY_RUNS:
        staggered, reference = SENSITIVITY_RUNS["staggered"]
        ours = benchmark.stats.stats.median
        difference = max(float(np.max(np.abs(S[:, 0, :] - S_ref[:, 0, :]).max(axis=0)
                                      / np.maximum(np.abs(S_ref[:, 0, :]).max(axis=0), 1e-300)))
                         for (_, S), (_, S_ref) in zip(out, reference))
        print(f"\nsensitivities of the pre-fit window: augmented {1e3 * ours:.0f} ms, staggered "
              f"{1e3 * staggered:.0f} ms -> {staggered / ours:.2f}x; largest difference of a position "
              f"sensitivity {100 * difference:.2g} % of its column's range")
