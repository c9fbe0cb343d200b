"""The friction asymmetry effect (``pneusim/model/effects/friction_asymmetry.py``): its physical signature, absent from the nominal
model."""

import numpy as np
import pytest

from pneusim.model import ActuatorModel, make_effect


def test_friction_asymmetry_multiplies_retracting_friction(rig2):
    factor = 2.5
    model = ActuatorModel([make_effect("friction_asymmetry", retract_factor=factor)])
    nominal = ActuatorModel()
    index = model.output_names.index("friction_force_N")
    viscous = rig2["friction_viscous_N_s_per_m"]
    for v in (0.005, 0.05, 0.3):
        x = np.array([0.1, v, 4e5, 4e5])
        f_ext = float(model.outputs(x, 5.0, model.param_vector(rig2))[index])
        f_nom = float(nominal.outputs(x, 5.0, nominal.param_vector(rig2))[index])
        assert f_ext == pytest.approx(f_nom)
        x[1] = -v
        f_ret = float(model.outputs(x, 5.0, model.param_vector(rig2))[index])
        assert f_ret - (-viscous * v) == pytest.approx(factor * (-(f_nom - viscous * v)), rel=1e-9)
