"""The pressure dependent friction effect (``pneusim/model/effects/pressure_dependent_friction.py``): its physical signature, absent from the nominal
model."""

import numpy as np
import pytest

from pneusim.model import ActuatorModel, make_effect
from pneusim.simulate import simulate


def test_pressure_dependent_friction_follows_the_seal_law(rig2):
    """Static and Coulomb levels scale by (1 + k|d|/S) / (1 + k d_ref/S), d = p_A - p_B, S = supply gauge;
    viscous friction does not; the breakaway (peak) force at two pressure differences differs by that ratio."""
    k, d_ref = 2.5, 4.0e4
    model = ActuatorModel([make_effect("pressure_dependent_friction", pressure_coefficient=k,
                                       reference_difference_Pa=d_ref)])
    nominal = ActuatorModel()
    index = model.output_names.index("friction_force_N")
    gauge = rig2["supply_Pa"] - rig2["atmosphere_Pa"]
    viscous = rig2["friction_viscous_N_s_per_m"]

    def friction(m, v, d):
        x = np.array([0.1, v, 3e5 + 0.5 * d, 3e5 - 0.5 * d])
        return float(m.outputs(x, 5.0, m.param_vector(rig2))[index])

    for d in (-4e5, -1e5, -d_ref, 2e4, d_ref, 1.5e5, 5.5e5):
        law = (1.0 + k * abs(d) / gauge) / (1.0 + k * d_ref / gauge)
        for v in (-0.2, -0.004, 0.002, 0.05):
            f_nom = friction(nominal, v, d)
            assert friction(model, v, d) - viscous * v == pytest.approx(law * (f_nom - viscous * v), rel=1e-6)
    # the level at the reference difference is the rig file's
    assert friction(model, 0.05, d_ref) == pytest.approx(friction(nominal, 0.05, d_ref), rel=1e-12)
    # breakaway: the peak of the seal friction (viscous part removed) near zero velocity, at 1 and 5 bar
    speeds = np.linspace(1e-5, 0.02, 400)
    low = max(friction(model, v, 1e5) - viscous * v for v in speeds)
    high = max(friction(model, v, 5e5) - viscous * v for v in speeds)
    assert high / low == pytest.approx((1.0 + k * 5e5 / gauge) / (1.0 + k * 1e5 / gauge), rel=1e-3)
    assert high / low > 2.0


def test_pressure_dependent_friction_moves_the_piston_and_vanishes_at_zero_coefficient(rig2, open_loop):
    """Along a simulated run the seal friction is the law at the simulated |p_A - p_B| (below the reference
    level while gliding, above it when accelerating), the position departs from the nominal model's by far
    more than sensor noise, and k = 0 is the nominal model to the solver's accuracy."""
    u = np.concatenate([np.full(10, 5.0), 5.0 + np.repeat(np.tile([2.0, -2.0], 3), 20), np.full(20, 5.0)])
    exp = open_loop(rig2, u)
    nominal = simulate(rig2, exp, noise_scale=0, rtol=1e-9)
    zero = simulate(rig2, exp, [make_effect("pressure_dependent_friction", pressure_coefficient=0.0)],
                    noise_scale=0, rtol=1e-9)
    assert np.max(np.abs(zero.state("position_m") - nominal.state("position_m"))) < 1e-9
    for name in ("pressure_a_Pa", "pressure_b_Pa"):
        assert np.max(np.abs(zero.state(name) - nominal.state(name))) < 1e-3
    k, d_ref = 3.0, 5e4
    sim = simulate(rig2, exp, [make_effect("pressure_dependent_friction", pressure_coefficient=k,
                                           reference_difference_Pa=d_ref)], noise_scale=0, rtol=1e-9)
    deviation = np.max(np.abs(sim.state("position_m") - nominal.state("position_m")))
    assert deviation > 10.0 * rig2["position_noise_std_m"]
    d = np.abs(sim.state("pressure_a_Pa") - sim.state("pressure_b_Pa"))
    assert d.min() < 0.8 * d_ref and d.max() > 1.5 * d_ref   # both sides of the reference are visited
    index = sim.model.output_names.index("friction_force_N")
    viscous = rig2["friction_viscous_N_s_per_m"]
    gauge = rig2["supply_Pa"] - rig2["atmosphere_Pa"]
    checked = 0
    for i in np.flatnonzero((d > 6e3) & (np.abs(sim.state("velocity_m_per_s")) > 1e-3)):
        x, v = sim.states[i], sim.states[i, 1]
        f = float(sim.model.outputs(x, u[i], sim.params)[index]) - viscous * v
        f0 = float(nominal.model.outputs(x, u[i], nominal.params)[index]) - viscous * v
        assert f == pytest.approx((1.0 + k * d[i] / gauge) / (1.0 + k * d_ref / gauge) * f0, rel=1e-6)
        checked += 1
    assert checked > 50
