"""CVODES forward sensitivities of the model against finite differences of the same integration."""

import numpy as np
import pytest

from pneusim.experiment import standard_experiment
from pneusim.fit import DEFAULT_FREE
from pneusim.model import ActuatorModel, make_effect
from pneusim.model.effects import EFFECTS
from pneusim.simulate import simulate
from pneusim.solver.sensitivity import SensitivitySimulator, command_schedule


@pytest.mark.parametrize("corrector", ["augmented", "staggered"])
@pytest.mark.parametrize("effects", [[], [make_effect("valve_dynamics", natural_frequency_Hz=15.0)]])
def test_sensitivities_match_central_differences(rig2, effects, corrector):
    exp = standard_experiment(rig2, "multisine", 3.0, "closed", seed=4)
    sim = simulate(rig2, exp, effects, noise_scale=0.0)
    model = ActuatorModel(effects)
    free = list(DEFAULT_FREE) + [n for e in effects for n in e.qualified()]
    params = model.param_vector(rig2)
    index = [model.param_names.index(n) for n in free]
    scales = params[index].copy()
    t, u = sim.recording.time_s, sim.recording.valve_cmd_V
    start, stop = 100, 160
    schedule = command_schedule(t, u, start, stop)
    x0 = sim.states[start]

    def run(p, x, rtol, sens):
        s = SensitivitySimulator(model, free, p, scales, rig2.stroke_m, rtol=rtol, corrector=corrector)
        return s, s.run(t[start], x, schedule, stop - start + 1, sens)

    s, (x, S) = run(params, x0, 1e-9, True)
    assert s.corrector == corrector
    # parameters: central differences of the tightly integrated samples
    for j, i in enumerate(index):
        h = 1e-4 * scales[j]
        plus, minus = params.copy(), params.copy()
        plus[i] += h
        minus[i] -= h
        fd = (run(plus, x0, 1e-11, False)[1][0] - run(minus, x0, 1e-11, False)[1][0]) / (2e-4)
        assert np.allclose(S[:, 0, j], fd[:, 0], rtol=2e-2, atol=2e-3 * np.abs(fd[:, 0]).max() + 1e-12), free[j]
    # initial state: columns are d x / d (x0 / x_scale)
    for k in range(len(x0)):
        h = 1e-5 * s.x_scale[k]
        plus, minus = x0.copy(), x0.copy()
        plus[k] += h
        minus[k] -= h
        fd = (run(params, plus, 1e-11, False)[1][0] - run(params, minus, 1e-11, False)[1][0]) / 2e-5
        assert np.allclose(S[:, 0, len(free) + k], fd[:, 0], rtol=2e-2,
                           atol=2e-3 * np.abs(fd[:, 0]).max() + 1e-12), model.state_names[k]


def test_command_schedule_delays_the_commands_the_valve_sees():
    t = np.arange(6) * 0.01
    u = np.array([5.0, 6.0, 7.0, 8.0, 9.0, 10.0])
    stops, seen, out = command_schedule(t, u, 1, 4, delay_s=0.015, command_before_V=4.0)
    # command k reaches the valve at t_k + 15 ms: before u[0] arrives it still sees the earlier 4 V
    assert np.allclose(stops, [0.015, 0.02, 0.025, 0.03, 0.035, 0.04])
    assert np.allclose(seen, [4.0, 5.0, 5.0, 6.0, 6.0, 7.0])
    assert list(out) == [-1, 1, -1, 2, -1, 3]
    stops, seen, out = command_schedule(t, u, 0, 5)
    assert np.allclose(stops, t[1:]) and np.allclose(seen, u[:-1]) and list(out) == [1, 2, 3, 4, 5]


def test_a_delay_of_whole_samples_gives_no_interval_of_rounding_length():
    """A delay of a whole number of samples lands each command on a later sample instant, up to rounding
    (0.342 + 0.008 > 0.35 in floating point): no integration interval may be that short (CVODES refuses
    to start one), every sample instant is an output, and the command seen on each sample interval is
    the one sent ``m`` samples earlier."""
    t = np.round(np.arange(1000) * 0.001, 6)           # as read from a CSV file with 1 ms sampling
    u = np.sin(np.arange(1000) * 0.37) + 5.0
    m = 8
    assert np.any(t[:-m] + m * 0.001 > t[m:])          # the rounding the test is about does occur
    for start in range(0, 990, 7):
        stops, seen, out = command_schedule(t, u, start, start + 10, delay_s=m * 0.001)
        assert np.diff(np.concatenate([[t[start]], stops])).min() > 1e-6
        assert list(out) == list(range(1, 11))
        sent = np.arange(start, start + 10) - m
        expected = np.where(sent >= 0, u[np.maximum(sent, 0)], u[0])
        assert np.allclose(seen, expected)


@pytest.mark.parametrize("effects", [(), tuple(EFFECTS)])
def test_small_linear_algebra_gives_sundials_results_to_the_last_bit(rig2, effects):
    """The fit's CVODES with ``small_vector.h``'s vectors (fused operations included) and
    ``small_dense.h``'s Newton solver (the default) against SUNDIALS' own serial vector, dense matrix
    and dense solver: states and sensitivities equal at every sample of a 3 s closed-loop stretch (four
    states with the default free set; nine with every effect on, beyond the unrolled kernels)."""
    model = ActuatorModel([make_effect(name) for name in effects])
    exp = standard_experiment(rig2, "multisine", 4.0, "closed", seed=6)
    sim = simulate(rig2, exp, model.effects, noise_scale=0.0)
    free = list(DEFAULT_FREE) + [n for e in model.effects for n in e.qualified()][:4]
    params = model.param_vector(rig2)
    scales = params[[model.param_names.index(n) for n in free]].copy()
    t, u = sim.recording.time_s, sim.recording.valve_cmd_V
    start, stop = 50, 350
    schedule = command_schedule(t, u, start, stop)
    out = {}
    for algebra in ("small", "sundials"):
        s = SensitivitySimulator(model, free, params, scales, rig2.stroke_m, linear_algebra=algebra,
                                 corrector="staggered")
        out[algebra] = s.run(t[start], sim.states[start], schedule, stop - start + 1, True)
    (x, S), (x_ref, S_ref) = out["small"], out["sundials"]
    assert x.shape[1] == (9 if effects else 4)
    assert np.ptp(x[:, 0]) > 0.01 and np.max(np.abs(S)) > 0      # the stretch moves, the sensitivities live
    assert np.array_equal(x, x_ref)
    assert np.array_equal(S, S_ref)


@pytest.mark.slow
def test_augmented_corrector_is_as_accurate_as_the_staggered_one_and_the_same_states(rig2):
    """The default corrector (state and sensitivities as one augmented state, :mod:`pneusim.solver.sensitivity`)
    against CVODES's staggered corrector, both at the fit's rtol 1e-6, on 40 segments of a closed-loop
    multisine that sticks and slips: the states agree to the tolerance, and each position-sensitivity
    column is as close to a reference (staggered, rtol 1e-10, sensitivity error control on) as the
    staggered corrector's: median and largest error within 1.5 times the staggered's (measured: the same
    largest error, 3.3 % of the column's range, and a median of 0.16 % against 0.15 %).  With CVODE's
    default Jacobian reuse (up to 20 steps) instead of a fresh block at every step the largest was 102 %."""
    from pneusim.solver import _cvodes_sensitivity as fast
    from pneusim.solver.backends import state_scales
    from pneusim.solver.sensitivity import _compiled_kernels
    model = ActuatorModel()
    exp = standard_experiment(rig2, "multisine", 22.0, "closed", seed=3)
    sim = simulate(rig2, exp, noise_scale=0.0)
    free = list(DEFAULT_FREE)
    params = model.param_vector(rig2)
    scales = params[[model.param_names.index(n) for n in free]].copy()
    t, u = sim.recording.time_s, sim.recording.valve_cmd_V
    runs = {}
    for name, corrector, rtol in (("augmented", "augmented", 1e-6), ("staggered", "staggered", 1e-6),
                                  ("reference", "staggered", 1e-10)):
        s = SensitivitySimulator(model, free, params, scales, rig2.stroke_m, rtol=rtol, corrector=corrector)
        if name == "reference":
            s._integrator = fast.SensitivityIntegrator(
                _compiled_kernels(model, tuple(free)), s.n, s.ns, s.params, s.weights, rtol,
                np.ascontiguousarray(rtol * state_scales(model, rig2.stroke_m)), sens_errcon=True)
        runs[name] = [s.run(t[k], sim.states[k], command_schedule(t, u, k, k + 50), 51, True)
                      for k in range(100, 2100, 50)]
    assert runs["augmented"] is not runs["staggered"]

    def errors(name):
        out = []
        for (x, S), (x_ref, S_ref) in zip(runs[name], runs["reference"]):
            assert np.abs(x[:, 0] - x_ref[:, 0]).max() < 2e-5          # m: the states to the tolerance
            out.append(np.abs(S[:, 0, :] - S_ref[:, 0, :]).max(axis=0) / np.abs(S_ref[:, 0, :]).max(axis=0))
        return np.array(out)

    augmented, staggered = errors("augmented"), errors("staggered")
    assert np.ptp(sim.states[100:2100, 0]) > 0.05                       # the stretch moves
    assert np.median(augmented) <= 1.5 * np.median(staggered) + 1e-6, (np.median(augmented), np.median(staggered))
    assert augmented.max() <= 1.5 * staggered.max() + 1e-6, (augmented.max(), staggered.max())
