"""The external load effect (``pneusim/model/effects/external_load.py``): its physical signature, absent from the nominal
model."""

import numpy as np
import pytest

from pneusim.model import ActuatorModel, make_effect


def test_external_load_adds_its_force(rig1):
    eff = make_effect("external_load", force_N=-20.0, stiffness_N_per_m=300.0)
    model, nominal = ActuatorModel([eff]), ActuatorModel()
    x = np.array([0.04, 0.0, 5e5, 5e5])
    a = float(model.rhs(x, 5.0, model.param_vector(rig1))[1])
    a0 = float(nominal.rhs(x, 5.0, nominal.param_vector(rig1))[1])
    assert (a - a0) * rig1["moving_mass_kg"] == pytest.approx(-20.0 - 300.0 * 0.04)


def test_the_state_at_rest_balances_the_load(rig1):
    """The initial state's pressures carry the load (the effect's static force), so the piston starts at rest:
    without it in the balance, a 60 N load would accelerate the piston at once."""
    eff = make_effect("external_load", force_N=-60.0, stiffness_N_per_m=400.0)
    model = ActuatorModel([eff])
    p = model.param_vector(rig1)
    position = 0.3 * rig1.stroke_m
    assert eff.static_force_N(model.param_dict(rig1), position) == -60.0 - 400.0 * position
    x = model.initial_state(rig1, position)
    accel = float(model.rhs(x, 5.0, p)[1])
    assert abs(accel) * rig1["moving_mass_kg"] < 1e-6
    unbalanced = ActuatorModel().initial_state(rig1, position)
    assert abs(float(model.rhs(unbalanced, 5.0, p)[1])) * rig1["moving_mass_kg"] > 50.0
