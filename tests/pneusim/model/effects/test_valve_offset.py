"""The valve offset effect (``pneusim/model/effects/valve_offset.py``): its physical signature, absent from the nominal
model."""

import numpy as np

from pneusim.model import make_effect
from pneusim.simulate import simulate


def test_valve_offset_drifts_at_nominal_null(rig1, open_loop):
    n = int(0.5 / rig1.sample_time_s)
    exp = open_loop(rig1, np.full(n, 5.0))
    drift = simulate(rig1, exp, [make_effect("valve_offset", offset_V=-0.2)], noise_scale=0)
    assert drift.state("position_m")[-1] - drift.state("position_m")[0] > 2e-3  # true null below 5 V: extends
