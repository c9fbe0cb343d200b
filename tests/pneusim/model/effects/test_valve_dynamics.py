"""The valve dynamics effect (``pneusim/model/effects/valve_dynamics.py``): its physical signature, absent from the nominal
model."""

import numpy as np
import pytest

from pneusim.model import make_effect
from pneusim.simulate import simulate


def test_valve_dynamics_lag_the_opening_and_vanish_when_fast(rig1, open_loop):
    rng = np.random.default_rng(3)
    u = 5.0 + np.repeat(rng.choice([-1.5, 1.5], 40), 25)
    u = np.concatenate([u, np.full(400, u[-1])])  # hold the last command until the spool settles
    exp = open_loop(rig1, u)
    nominal = simulate(rig1, exp, noise_scale=0)
    slow = simulate(rig1, exp, [make_effect("valve_dynamics", natural_frequency_Hz=8.0, damping=0.7)], noise_scale=0)
    fast = simulate(rig1, exp, [make_effect("valve_dynamics", natural_frequency_Hz=2000.0, damping=0.7)],
                    noise_scale=0)
    err_slow = np.max(np.abs(slow.state("position_m") - nominal.state("position_m")))
    err_fast = np.max(np.abs(fast.state("position_m") - nominal.state("position_m")))
    assert err_slow > 1e-3
    assert err_fast < 0.02 * err_slow
    # spool state settles on the commanded opening
    assert slow.state("spool_opening")[-1] == pytest.approx((u[-1] - 5.0) / 5.0, abs=1e-3)
