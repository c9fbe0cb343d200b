"""The transport delay effect (``pneusim/model/effects/transport_delay.py``): its physical signature, absent from the nominal
model."""

import numpy as np

from pneusim.model import make_effect
from pneusim.simulate import simulate


def test_transport_delay_shifts_the_response_by_the_delay(rig2, open_loop):
    # doublets after a rest at null, so the delayed valve has seen the same history
    u = np.concatenate([np.full(10, 5.0), 5.0 + np.repeat(np.tile([1.0, -1.0], 15), 20)])
    exp = open_loop(rig2, u)
    nominal = simulate(rig2, exp, noise_scale=0)
    m = 3
    delayed = simulate(rig2, exp, [make_effect("transport_delay", delay_s=m * rig2.sample_time_s)], noise_scale=0)
    shifted = nominal.state("position_m")[:-m]
    assert np.max(np.abs(delayed.state("position_m")[m:] - shifted)) < 1e-6
    # a fractional delay lies between the neighbouring whole-sample delays in timing
    half = simulate(rig2, exp, [make_effect("transport_delay", delay_s=2.5 * rig2.sample_time_s)], noise_scale=0)
    x_half = half.state("position_m")
    assert np.max(np.abs(x_half[3:] - nominal.state("position_m")[:-3])) > 1e-5
