"""The heat transfer effect (``pneusim/model/effects/heat_transfer.py``): its physical signature, absent from the nominal
model."""

import numpy as np

from pneusim.model import make_effect
from pneusim.simulate import simulate


def test_heat_transfer_relaxes_chamber_temperature_after_a_fast_move(rig2, open_loop):
    n_move, n_rest = int(0.15 / rig2.sample_time_s), int(1.5 / rig2.sample_time_s)
    u = np.concatenate([np.full(n_move, 8.0), np.full(n_rest, 5.0)])
    exp = open_loop(rig2, u, position=0.05)
    tau = 0.1
    heat = simulate(rig2, exp, [make_effect("heat_transfer", time_constant_s=tau)], noise_scale=0)
    adiabatic = simulate(rig2, exp, noise_scale=0)
    temps = heat.state("temperature_b_K")
    assert temps[:n_move].min() < 293.15 - 2.0 or temps[:n_move].max() > 293.15 + 2.0  # fast move: far from wall
    five_tau = n_move + int(5 * tau / rig2.sample_time_s)
    assert np.all(np.abs(heat.state("temperature_b_K")[five_tau:] - 293.15) < 0.1)
    # the pressure after the move differs from the adiabatic chamber's by more than sensor noise
    diff = np.abs(heat.state("pressure_b_Pa")[n_move:] - adiabatic.state("pressure_b_Pa")[n_move:])
    assert diff.max() > 3e3
