"""The effect registry: every effect composes, the command-line form, and the fit's bounds of every freed
effect parameter (each effect's own tests are in ``tests/pneusim/model/effects/``)."""

import numpy as np
import pytest

from pneusim.errors import PneusimError
from pneusim.experiment import Experiment
from pneusim.model import ActuatorModel, EFFECTS, make_effect, parse_effect_text
from pneusim.simulate import simulate


def _open(rig, command, position=None, warmup_s=0.0):
    return Experiment("open", rig.sample_time_s, np.asarray(command, float), warmup_s=warmup_s,
                      initial_position_m=0.5 * rig.stroke_m if position is None else position)


def test_every_effect_of_the_vocabulary_exists_and_composes(rig2):
    assert set(EFFECTS) == {"leakage", "valve_deadband", "valve_offset", "valve_dynamics", "transport_delay",
                            "heat_transfer", "friction_asymmetry", "supply_pressure_droop", "external_load",
                            "pressure_dependent_friction"}
    everything = [make_effect(name) for name in EFFECTS]
    n = int(2.0 / rig2.sample_time_s)
    sim = simulate(rig2, _open(rig2, 5.0 + np.sign(np.sin(np.arange(n) * 0.05))), everything, noise_scale=0)
    assert np.all(np.isfinite(sim.states))


def test_effect_text_and_bad_effects():
    eff = parse_effect_text("valve_deadband:deadband_V=0.3")
    assert eff.values == {"deadband_V": 0.3}
    with pytest.raises(PneusimError, match="unknown effect"):
        parse_effect_text("backlash:gap_m=1")
    with pytest.raises(PneusimError, match="no parameter"):
        parse_effect_text("valve_offset:offset=1")
    with pytest.raises(PneusimError, match="must be one of"):
        make_effect("leakage", kind="sideways")
    with pytest.raises(PneusimError, match="expected NAME:PARAM=VALUE"):
        parse_effect_text("valve_offset:0.2")
    with pytest.raises(PneusimError, match="once"):
        ActuatorModel([make_effect("valve_offset"), make_effect("valve_offset")])


def test_fit_bounds_of_every_effect_parameter_lie_in_its_physical_range():
    """Whatever the optimiser returns inside the fit's bounds makes a valid effect: both ends of every
    freed effect parameter's bounds, from its default and from a start of zero, are accepted by the
    effect (a spring stiffness of -118 N/m once ended a diagnosis refit)."""
    from pneusim.fit import EFFECT_FREE
    from pneusim.fit.parameters import parameter_bounds
    from pneusim.model.effects import in_range

    checked = 0
    for effect_name, qualified in EFFECT_FREE.items():
        cls = EFFECTS[effect_name]
        for q in qualified:
            key = q.split(".", 1)[1]
            for start in {cls.parameters[key], 0.0}:
                lo, hi = parameter_bounds(q, start)
                assert lo < hi, (q, start, lo, hi)
                for value in (lo, hi):
                    assert in_range(value, cls.ranges.get(key)), (q, start, value)
                    make_effect(effect_name, **{key: value})
                checked += 1
    assert checked >= 10


def test_fit_bounds_do_not_shrink_with_a_start_near_zero():
    """Diagnosis starts an effect where its screening left it, often near zero; where the fit knows a
    parameter's typical magnitude, its bounds must not follow the start down (a load screened at
    -0.87 N once bounded the refit to +-43 N, and a -100 N load was refused)."""
    from pneusim.fit import EFFECT_FREE
    from pneusim.fit.parameters import _TABLE, parameter_bounds

    checked = 0
    for qualified in EFFECT_FREE.values():
        for q in qualified:
            typical = _TABLE.get(q, (None,))[0]
            if typical is None:
                continue
            for start in (1e-3 * typical, 0.0):
                assert parameter_bounds(q, start) == parameter_bounds(q, typical), q
            checked += 1
    assert checked >= 6
    lo, hi = parameter_bounds("external_load.force_N", -0.87)
    assert lo <= -1000.0 and hi >= 1000.0
