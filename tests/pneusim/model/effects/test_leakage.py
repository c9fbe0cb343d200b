"""The leakage effect (``pneusim/model/effects/leakage.py``): its physical signature, absent from the nominal
model."""

import numpy as np

from pneusim.model import make_effect
from pneusim.simulate import simulate


def test_internal_leak_equalises_pressures_at_null(rig2, open_loop):
    n = int(5.0 / rig2.sample_time_s)
    exp = open_loop(rig2, np.full(n, 5.0))
    tight = simulate(rig2, exp, noise_scale=0)
    leaky = simulate(rig2, exp, [make_effect("leakage", kind="internal", conductance_kg_per_s_Pa=4e-9)],
                     noise_scale=0)
    gap0 = abs(tight.state("pressure_a_Pa")[0] - tight.state("pressure_b_Pa")[0])
    assert gap0 > 1e4
    assert np.ptp(tight.state("pressure_a_Pa")) < 1e-3
    gap_end = abs(leaky.state("pressure_a_Pa")[-1] - leaky.state("pressure_b_Pa")[-1])
    assert gap_end < 0.3 * gap0
    # the piston creeps while holding: the force balance moves with the pressures
    assert np.ptp(leaky.state("position_m")) > 1e-3


def test_external_leak_lets_the_chamber_relax_to_atmosphere(rig1, open_loop):
    n = int(3.0 / rig1.sample_time_s)
    leaky = simulate(rig1, open_loop(rig1, np.full(n, 5.0)),
                     [make_effect("leakage", kind="external", chamber="b", conductance_kg_per_s_Pa=2e-9)], noise_scale=0)
    p_b = leaky.state("pressure_b_Pa")
    assert p_b[-1] < p_b[0] - 0.5 * (p_b[0] - rig1["atmosphere_Pa"])
