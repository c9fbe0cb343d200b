"""The plant stepped sample by sample gives the same run as the batch simulator."""

import numpy as np

from pneusim.experiment import standard_experiment
from pneusim.plant import SimulatedPlant
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
