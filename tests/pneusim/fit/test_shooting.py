"""The multiple-shooting problem's residuals, continuity defects and their sparse Jacobians.

The Jacobians come from CVODES's forward sensitivities, gathered per output and segment into SciPy CSR
matrices; here they are checked against central differences of the residuals themselves (integrated
far more tightly), on a window with both pressures recorded and gaps in two signals.
"""

import numpy as np
import pytest
from scipy import sparse

from pneusim.experiment import standard_experiment
from pneusim.fit import DEFAULT_FREE
from pneusim.fit.shooting import FitData, ShootingProblem, _csr_pattern, expected_position_reading
from pneusim.fit.trust_region import _StackedJacobian
from pneusim.model import ActuatorModel
from pneusim.simulate import simulate


@pytest.fixture(scope="module")
def window(rig2):
    """240 samples of a closed-loop multisine (noise on, both pressures), with a gap of 3 position samples
    and one of 5 cap-end pressure samples, the true segment start states slightly perturbed."""
    exp = standard_experiment(rig2, "multisine", 4.0, "closed", seed=11)
    sim = simulate(rig2, exp, seed=3, record_pressures=True)
    rec = sim.recording
    first, n = 100, 240
    position = rec.position_m[first:first + n].copy()
    pressure_a = rec.pressure_a_Pa[first:first + n].copy()
    position[57:60] = np.nan
    pressure_a[130:135] = np.nan
    signals = {"position_m": (position, rig2["position_noise_std_m"]),
               "pressure_a_Pa": (pressure_a, rig2["pressure_noise_std_Pa"]),
               "pressure_b_Pa": (rec.pressure_b_Pa[first:first + n].copy(), rig2["pressure_noise_std_Pa"])}
    data = FitData(rec.time_s[first:first + n], rec.valve_cmd_V[first:first + n], float(rec.valve_cmd_V[first - 1]),
                   signals)
    model = ActuatorModel(())
    params = model.param_vector(rig2)
    scales = params[[model.param_names.index(k) for k in DEFAULT_FREE]].copy()

    def problem(rtol):
        return ShootingProblem(model, params, DEFAULT_FREE, scales, data, rig2.stroke_m, 40, rtol=rtol, threads=2)

    pb = problem(1e-8)
    starts = sim.states[first + pb.starts] * (1.0 + 0.01 * np.sin(np.arange(pb.n_segments * pb.n)).reshape(-1, pb.n))
    theta = np.array([1.05, 0.97, 1.02, 0.95, 1.1, 0.9, 1.03])
    v = pb.join(theta, starts)
    yield pb, problem, v, data
    pb.close()


def test_residuals_are_each_sample_against_its_segment(window):
    """Every residual is a recorded sample against the segment's own integration from its start state
    (the position as the range-limited sensor reads it), divided by the noise; a gap gives no row; the
    defects are each segment's end against the next one's start, in tolerance units."""
    pb, _, v, data = window
    e = pb.evaluate(v, derivatives=False)
    assert e["ok"]
    theta, starts = pb.split(v)
    for sim in pb.sims:
        sim.set_params(pb.params_of(theta))
    expected, defects = [], []
    for j in range(pb.n_segments):
        n_out = pb.stops[j] - pb.starts[j] + 1
        x, _ = pb.sims[0].run(data.time_s[pb.starts[j]], starts[j], pb.schedules[j], n_out, False)
        samples = pb.samples_of(j)
        for name, (values, sigma) in data.signals.items():
            i = pb.model.state_names.index(name)
            kept = samples[np.isfinite(values[samples])]
            model_out = x[kept - pb.starts[j], i]
            if name == "position_m":
                model_out = expected_position_reading(model_out, pb.stroke_m, sigma)[0]
            expected.append((model_out - values[kept]) / sigma)
        if j < pb.n_segments - 1:
            defects.append((x[-1] - starts[j + 1]) / pb.g_scale)
    n_rows = sum(int(np.isfinite(values).sum()) for values, _ in data.signals.values())
    assert pb.n_residuals == n_rows == e["r"].size
    assert np.array_equal(e["r"], np.concatenate(expected))
    assert np.array_equal(e["g"], np.concatenate(defects))


@pytest.mark.slow
def test_jacobians_match_central_differences(window):
    pb, problem, v, _ = window
    jr, jg = pb.jacobians(v)
    assert sparse.isspmatrix_csr(jr) and jr.shape == (pb.n_residuals, pb.n_v)
    assert jg.shape == (pb.n_constraints, pb.n_v)
    tight = problem(1e-11)
    try:
        for c in range(pb.n_v):
            h = 1e-5
            plus, minus = v.copy(), v.copy()
            plus[c] += h
            minus[c] -= h
            ep, em = tight.evaluate(plus, derivatives=False), tight.evaluate(minus, derivatives=False)
            for exact, name in ((jr, "r"), (jg, "g")):
                fd = (ep[name] - em[name]) / (2 * h)
                column = exact[:, c].toarray().ravel()
                scale = max(np.abs(fd).max(), 1e-9)
                assert np.allclose(column, fd, rtol=2e-2, atol=2e-3 * scale), (name, c)
    finally:
        tight.close()


def test_stacked_jacobian_multiplies_as_the_matrix_does():
    """The trust region's operator gives SciPy's own products of the matrix and of its transpose, to the bit."""
    rng = np.random.default_rng(0)
    matrix = sparse.random(300, 40, density=0.1, random_state=rng, format="csr")
    op = _StackedJacobian(matrix)
    x, y, X = rng.normal(size=40), rng.normal(size=300), rng.normal(size=(40, 3))
    assert np.array_equal(op.matvec(x), matrix @ x)
    assert np.array_equal(op.rmatvec(y), matrix.T @ y)
    assert np.array_equal(op.matmat(X), matrix @ X)
    assert np.array_equal(op.rmatmat(y[:, None]), matrix.T @ y[:, None])


def test_csr_pattern_is_scipy_conversion_and_refuses_a_repeated_entry():
    rows, cols = np.array([2, 0, 1, 0, 2]), np.array([1, 3, 0, 0, 0])
    data = np.array([1.5, -2.0, 3.0, 4.0, 5.0])
    build = _csr_pattern(rows, cols, (3, 4))
    reference = sparse.csr_matrix((data, (rows, cols)), shape=(3, 4))
    built = build(data)
    assert np.array_equal(built.indptr, reference.indptr) and np.array_equal(built.indices, reference.indices)
    assert np.array_equal(built.data, reference.data)
    with pytest.raises(ValueError, match="twice"):
        _csr_pattern(np.array([0, 0]), np.array([1, 1]), (1, 2))


def test_screening_cost_is_the_trust_regions_objective(window):
    """Diagnosis compares costs before and after a trust region's steps: both are the objective the trust
    region minimises, integrated with sensitivities as it integrates every point (the augmented corrector
    steps differently from the state's own memory, so a cost of the same point without sensitivities can
    differ, by 12 % on a chaotic stick-slip window), and the steps never end above their start."""
    from pneusim.diagnosis.candidates import DEFECT_WEIGHT, _total_cost
    from pneusim.fit.trust_region import trust_region

    pb, _, v, _ = window
    lower = np.full(v.size, -np.inf)
    upper = np.full(v.size, np.inf)
    lower[:pb.n_free], upper[:pb.n_free] = 0.2, 5.0

    def objective(x):
        pb._cache_key = None
        e = pb.evaluate(x, derivatives=True)
        return float(np.dot(e["r"], e["r"]) + DEFECT_WEIGHT ** 2 * np.dot(e["g"], e["g"]))

    pb._cache_key = None
    start = _total_cost(pb, v)
    assert start == objective(v)
    end_v, _, _ = trust_region(pb, v, lower, upper, max_evaluations=6, defect_weight=DEFECT_WEIGHT)
    pb._cache_key = None
    assert _total_cost(pb, end_v) == objective(end_v) <= start


def test_a_filter_pass_stops_at_its_next_sample_once_a_callers_deadline_has_passed(window, monkeypatch):
    """A filter pass integrates one sample at a time, and where the model is stiff at the point tried one pass can
    take minutes: under a caller's work deadline (:func:`pneusim.fit.deadline.work_deadline`) it checks before
    every sample and stops there, raising :class:`~pneusim.fit.deadline.FitDeadlineExceeded`; without one it runs
    every sample.  Each sample charges its CVODES steps, the same steps in every pass from the same point, so the
    pass stops after exactly the samples the deadline leaves room for, on any machine; the processor-time
    backstop stops it too, with the work deadline far away."""
    from types import SimpleNamespace

    from pneusim.fit import deadline
    from pneusim.fit.tracking import process_std, run_filter
    from pneusim.solver import work

    pb, _, v, _ = window
    theta, starts = pb.split(v)
    sim, steps = pb.sims[0], []
    step = sim.step_into
    monkeypatch.setattr(sim, "step_into", lambda *args: steps.append(work.done()) or step(*args))
    full = run_filter(pb, theta, starts[0], process_std(pb, 1e-3))
    assert full["ok"] and len(steps) == pb.data.n_samples - 1
    before_each = np.array(steps) - steps[0]                  # the units counted before each sample, from the pass's start
    assert np.all(np.diff(before_each) > 0)
    steps.clear()
    with deadline.work_deadline(work.done() + before_each[50]) as block:
        with pytest.raises(deadline.FitDeadlineExceeded):
            run_filter(pb, theta, starts[0], process_std(pb, 1e-3))
    assert block.reached and not block.by_backstop and len(steps) == 51   # samples 0-50 began within it
    ticks = iter(range(10 ** 6))   # the processor clock a counter, one tick a look
    monkeypatch.setattr(deadline, "time", SimpleNamespace(process_time=lambda: float(next(ticks))))
    steps.clear()
    with deadline.work_deadline(work.done() + 1e12, cpu_at_s=100.0) as block:
        with pytest.raises(deadline.FitDeadlineExceeded):
            run_filter(pb, theta, starts[0], process_std(pb, 1e-3))
    assert block.reached and block.by_backstop and 0 < len(steps) < 120


def test_a_filter_pass_that_must_stop_at_a_failed_sample_takes_no_sample_after_it(window, monkeypatch):
    """A trial point the model cannot be integrated at fails at every sample from there on, each failure after the
    integrator's whole step allowance.  The prediction-error fit discards a pass with a failed sample, so its passes
    stop there (``stop_at_failure``): not ok, and not one more sample integrated, whether the integrator raised or
    left a non-finite state.  Without it the pass goes on to the end (a failed sample's prediction keeps the state
    as it was, the measurements still update it), and its states before the failure are the same."""
    from pneusim.errors import SolverError
    from pneusim.fit.tracking import process_std, run_filter

    pb, _, v, _ = window
    theta, starts = pb.split(v)
    sim, calls = pb.sims[0], []
    step = sim.step_into
    for failing in ("raises", "nan"):
        def failing_from_sample_20(t0, x, schedule, x_out, s_out):
            calls.append(t0)
            if len(calls) < 20:
                return step(t0, x, schedule, x_out, s_out)
            if failing == "raises":
                raise SolverError("too much work")
            x_out[1] = np.nan
        monkeypatch.setattr(sim, "step_into", failing_from_sample_20)
        calls.clear()
        stopped = run_filter(pb, theta, starts[0], process_std(pb, 1e-3), gradients=True, stop_at_failure=True)
        assert not stopped["ok"] and len(calls) == 20
        calls.clear()
        whole = run_filter(pb, theta, starts[0], process_std(pb, 1e-3), gradients=True)
        assert not whole["ok"] and len(calls) == pb.data.n_samples - 1
        np.testing.assert_array_equal(stopped["states"][:20], whole["states"][:20])
        assert np.all(np.isfinite(whole["states"][20:]))   # the measurements alone move it on


def test_the_filter_holds_the_states_a_recording_does_not_measure(window, rig2):
    """The prediction-error fit's process noise: every state at its fraction of the state's typical magnitude (the
    position at 1e-3 of that), and the states the recording does not measure beyond the piston's motion at
    ``unmeasured_factor`` of it: chamber pressures where the window does not measure them, and an effect's own
    states (here the chamber temperatures of heat transfer) always, measured pressures or not."""
    from pneusim.fit.tracking import process_std
    from pneusim.model import make_effect
    from pneusim.solver.backends import state_scales

    _, _, _, data = window
    position_only = FitData(data.time_s, data.command_V, data.command_before_V,
                            {"position_m": data.signals["position_m"]})
    for signals, unmeasured in ((data, set()), (position_only, {"pressure_a_Pa", "pressure_b_Pa"})):
        model = ActuatorModel([make_effect("heat_transfer")])
        params = model.param_vector(rig2)
        scales = params[[model.param_names.index(k) for k in DEFAULT_FREE]].copy()
        pb = ShootingProblem(model, params, DEFAULT_FREE, scales, signals, rig2.stroke_m, 40, threads=1)
        try:
            held = process_std(pb, 1e-2, 0.01) / (1e-2 * state_scales(model, rig2.stroke_m))
        finally:
            pb.close()
        expected = {"position_m": 1e-3, "velocity_m_per_s": 1.0, "pressure_a_Pa": 1.0, "pressure_b_Pa": 1.0,
                    "temperature_a_K": 0.01, "temperature_b_K": 0.01}
        expected.update({name: 0.01 for name in unmeasured})
        assert dict(zip(model.state_names, held)) == pytest.approx(expected)


def test_ipopt_stopped_by_a_callers_deadline_raises_it_once_and_prints_nothing(window, capfd):
    """An IPOPT solve that meets a caller's work deadline mid-way ends there and raises
    :class:`~pneusim.fit.deadline.FitDeadlineExceeded` to the caller, as every other route does; the solver's
    callbacks do not let the error through CasADi, which would print its traceback and the whole point for every
    evaluation IPOPT retried (hundreds of kilobytes on a terminal).  Without a deadline the same solve runs to
    its end."""
    from pneusim.fit import deadline
    from pneusim.fit.nlp import solve_ipopt
    from pneusim.solver import work

    pb, _, v, _ = window
    lower, upper = np.full(v.size, -np.inf), np.full(v.size, np.inf)
    lower[:pb.n_free], upper[:pb.n_free] = 0.2, 5.0
    before = work.done()
    whole = solve_ipopt(pb, v, lower, upper, max_iter=8)
    units = work.done() - before
    assert whole.iterations > 2 and np.isfinite(whole.objective)
    capfd.readouterr()
    with deadline.work_deadline(work.done() + 0.5 * units) as block:
        with pytest.raises(deadline.FitDeadlineExceeded):
            solve_ipopt(pb, v, lower, upper, max_iter=8)
    assert block.reached
    out, err = capfd.readouterr()
    assert "Traceback" not in err and "Traceback" not in out and len(err) + len(out) == 0
