"""The plant stepped sample by sample gives the same run as the batch simulator.

:func:`simulate` runs its sample loop in C when the parts are the built-in ones
(:meth:`SimulatedPlant.compiled_loop`); those runs must be the generic Python
loop's to the last bit.
"""

import numpy as np
import pytest

from pneusim.controller import ProportionalController
from pneusim.errors import SolverError
from pneusim.experiment import standard_experiment
from pneusim.model import make_effect
from pneusim.plant import SimulatedPlant
from pneusim.rig import load_rig
from pneusim.sensors import Sensors
from pneusim.simulate import simulate


def test_stepping_the_plant_by_hand_reproduces_simulate(rig1):
    exp = standard_experiment(rig1, "pulses", 0.5, "closed", seed=3)
    batch = simulate(rig1, exp, seed=11)
    plant = SimulatedPlant(rig1, seed=11)
    ctrl = exp.controller
    n_warm = int(round(exp.warmup_s / exp.sample_time_s))
    ref0 = exp.signal[0]
    plant.reset(ref0, ctrl.command(0.0, ref0, ref0), t0_s=-n_warm * exp.sample_time_s)
    positions = []
    for k in range(-n_warm, exp.n_samples):
        reading = plant.measure()
        u = ctrl.command(reading.t_s, exp.signal[max(k, 0)], reading.position_m)
        if k >= 0:
            positions.append(reading.position_m)
        plant.step(u)
    assert np.array_equal(np.array(positions), batch.recording.position_m)
    assert abs(plant.t_s - exp.n_samples * exp.sample_time_s) < 1e-12


# --- the compiled sample loop -------------------------------------------------------------------

LOOP_CASES = {
    "paper1 closed, noisy sensors": ("paper1-mre", "pulses", 2.0, "closed", (), 1.0),
    "paper2 closed, ideal sensors": ("paper2-enfield", "multisine", 4.0, "closed", (), 0.0),
    "paper2 open": ("paper2-enfield", "steps", 4.0, "open", (), 1.0),
    "paper1 closed, transport delay": ("paper1-mre", "pulses", 2.0, "closed",
                                       (("transport_delay", {"delay_s": 0.0035}),), 1.0),
    "paper2 open, delay of 2 samples": ("paper2-enfield", "steps", 4.0, "open",
                                        (("transport_delay", {"delay_s": 0.02}),), 1.0),
    "paper1 closed, valve dynamics and leakage": ("paper1-mre", "pulses", 2.0, "closed",
                                                  (("valve_dynamics", {}), ("leakage", {})), 1.0),
}


def _run_both(rig_name, kind, duration, loop, effects, noise, progress=False):
    rig = load_rig(rig_name)
    exp = standard_experiment(rig, kind, duration, loop, seed=4)
    effects = [make_effect(name, **values) for name, values in effects]
    return [simulate(rig, exp, effects, seed=9, noise_scale=noise, progress=progress and compiled, compiled=compiled)
            for compiled in (True, False)]


@pytest.mark.parametrize("case", list(LOOP_CASES))
def test_compiled_loop_gives_the_python_loops_recording_bit_for_bit(case):
    """The sample loop in C (built-in sensors, controller, CVODE) against the generic Python loop."""
    fast, generic = _run_both(*LOOP_CASES[case])
    assert np.ptp(generic.state("position_m")) > 0.01  # the run moves
    for column in ("position_m", "valve_cmd_V", "pressure_a_Pa", "pressure_b_Pa"):
        assert np.array_equal(getattr(fast.recording, column), getattr(generic.recording, column)), column
    assert np.array_equal(fast.states, generic.states)
    assert fast.solver_stats == generic.solver_stats
    assert fast.recording.metadata == generic.recording.metadata


def test_compiled_loop_reports_a_cvode_failure_as_the_python_loop_does(rig2):
    """CVODE's failure inside the C loop: the same SolverError (time, CVODE's message, state)."""
    exp = standard_experiment(rig2, "multisine", 2.0, "closed", seed=1)
    messages = []
    for compiled in (True, False):
        with pytest.raises(SolverError, match=r"cvode failed at t = .*mxstep.*position_m=") as info:
            simulate(rig2, exp, noise_scale=0, compiled=compiled, solver_options={"max_steps": 3})
        messages.append(str(info.value))
    assert messages[0] == messages[1]


def test_compiled_loop_in_chunks_with_a_progress_bar_gives_the_same_run():
    fast, generic = _run_both(*LOOP_CASES["paper1 closed, transport delay"], progress=True)
    assert np.array_equal(fast.states, generic.states)
    assert np.array_equal(fast.recording.position_m, generic.recording.position_m)


def test_compiled_loop_only_for_the_built_in_parts(rig1):
    class Doubled(ProportionalController):
        def command(self, t_s, reference_m, measured_m):
            return super().command(t_s, reference_m, measured_m) * 2

    def plant(**options):
        p = SimulatedPlant(rig1, **options)
        p.reset(0.1, 5.0)
        return p

    ctrl = ProportionalController(20.0)
    assert plant().compiled_loop(ctrl) is not None
    assert plant().compiled_loop(None) is not None  # open loop
    assert plant().compiled_loop(Doubled(20.0)) is None
    assert plant().compiled_loop(lambda t, r, y: 5.0) is None
    assert plant(backend="scipy-radau").compiled_loop(ctrl) is None


def test_another_controller_runs_in_the_python_loop(rig1):
    """A controller that is not exactly the built-in one is called once a sample from Python."""
    class Counting(ProportionalController):
        calls = 0

        def command(self, t_s, reference_m, measured_m):
            Counting.calls += 1
            return super().command(t_s, reference_m, measured_m)

    exp = standard_experiment(rig1, "pulses", 0.5, "closed", seed=3)
    builtin = simulate(rig1, exp, seed=1)
    ctrl = exp.controller
    exp.controller = Counting(ctrl.kp_V_per_m, ctrl.u0_V, ctrl.u_min_V, ctrl.u_max_V)
    counted = simulate(rig1, exp, seed=1)
    n_warm = int(round(exp.warmup_s / exp.sample_time_s))
    assert Counting.calls == 1 + n_warm + exp.n_samples  # the reset's command, then one a sample
    assert np.array_equal(counted.recording.valve_cmd_V, builtin.recording.valve_cmd_V)
    assert np.array_equal(counted.states, builtin.states)


def test_plant_continues_by_hand_where_the_compiled_loop_stopped(rig1):
    """sync_from hands time, state, held command and pending delayed commands back to the plant."""
    effects = [make_effect("transport_delay", delay_s=0.0035)]
    ctrl = ProportionalController(30.0)
    signal = np.where(np.arange(400) < 200, 0.05, 0.12)

    def by_hand(plant, k_from, k_to, positions):
        for k in range(k_from, k_to):
            reading = plant.measure()
            positions[k] = reading.position_m
            plant.step(ctrl.command(reading.t_s, signal[k], reading.position_m))

    reference = SimulatedPlant(rig1, effects, seed=5)
    reference.reset(0.05, 5.0)
    expected = np.empty(400)
    by_hand(reference, 0, 400, expected)

    plant = SimulatedPlant(rig1, effects, seed=5)
    plant.reset(0.05, 5.0)
    loop = plant.compiled_loop(ctrl)
    got, commands, pa, pb = np.empty(400), np.empty(400), np.empty(400), np.empty(400)
    states = np.empty((400, len(plant.model.state_names)))
    normals = plant.sensors.take_normals(150 * loop.normals_per_sample)
    flag, _, _ = loop.run(0, 150, 400, signal, normals, got, commands, pa, pb, states)
    assert flag == 0 and loop.k == 150 and len(loop.pending) > 0
    plant.sync_from(loop)
    assert abs(plant.t_s - 150 * rig1.sample_time_s) < 1e-12
    by_hand(plant, 150, 400, got)
    assert np.array_equal(got, expected)
    assert np.array_equal(plant.state, reference.state)


def test_sensors_hand_out_the_same_noise_stream_in_blocks(rig2):
    one_by_one, in_blocks = Sensors(rig2, seed=3), Sensors(rig2, seed=3)
    draws = [one_by_one._normal() for _ in range(9003)]
    blocks = np.concatenate([in_blocks.take_normals(m) for m in (1, 4094, 0, 3, 4905)])
    assert np.array_equal(blocks, draws)
    assert one_by_one._normal() == in_blocks._normal()  # and both continue alike
