"""The valve deadband effect (``pneusim/model/effects/valve_deadband.py``): its physical signature, absent from the nominal
model."""

import numpy as np
import pytest

from pneusim.model import ActuatorModel, make_effect
from pneusim.simulate import simulate


def test_deadband_stops_motion_for_small_commands(rig2, open_loop):
    d = 0.4
    n = int(1.0 / rig2.sample_time_s)
    small = open_loop(rig2, np.full(n, 5.0 + 0.8 * d))
    nominal = simulate(rig2, small, noise_scale=0)
    banded = simulate(rig2, small, [make_effect("valve_deadband", deadband_V=d)], noise_scale=0)
    assert np.ptp(nominal.state("position_m")) > 0.01
    assert np.ptp(banded.state("position_m")) < 1e-9
    # a large command still gets full opening at full command
    model = ActuatorModel([make_effect("valve_deadband", deadband_V=d)])
    x = model.initial_state(rig2, 0.1)
    opening = np.asarray(model.outputs(x, 10.0, model.param_vector(rig2))).ravel()[0]
    assert opening == pytest.approx(1.0)
