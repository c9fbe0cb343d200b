"""The supply pressure droop effect (``pneusim/model/effects/supply_pressure_droop.py``): its physical signature, absent from the nominal
model."""

import numpy as np
import pytest

from pneusim.model import make_effect
from pneusim.simulate import simulate


def test_supply_droops_during_long_moves_and_recovers(rig2, open_loop):
    n_move, n_rest = int(0.4 / rig2.sample_time_s), int(2.0 / rig2.sample_time_s)
    u = np.concatenate([np.full(n_move, 10.0), np.full(n_rest, 5.0)])
    eff = make_effect("supply_pressure_droop", supply_volume_m3=2e-4, supply_conductance_m3_per_s_Pa=5e-9,
                      regulator_Pa=rig2["supply_Pa"])
    sim = simulate(rig2, open_loop(rig2, u, position=0.02), [eff], noise_scale=0)
    supply = sim.state("supply_pressure_Pa")
    assert supply.min() < 0.9 * rig2["supply_Pa"]
    assert supply[-1] == pytest.approx(rig2["supply_Pa"], rel=1e-3)
    nominal = simulate(rig2, open_loop(rig2, u, position=0.02), noise_scale=0)
    k = np.argmax(nominal.state("position_m") > 0.2)
    assert sim.state("position_m")[k] < nominal.state("position_m")[k]  # slower under droop
