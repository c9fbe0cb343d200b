"""Each optional effect shows its physical signature, and the nominal model without it does not."""

import numpy as np
import pytest

from pneusim.errors import PneusimError
from pneusim.experiment import Experiment
from pneusim.model import ActuatorModel, EFFECTS, make_effect, parse_effect_text
from pneusim.simulate import simulate


def _open(rig, command, position=None, warmup_s=0.0):
    return Experiment("open", rig.sample_time_s, np.asarray(command, float), warmup_s=warmup_s,
                      initial_position_m=0.5 * rig.stroke_m if position is None else position)


def test_internal_leak_equalises_pressures_at_null(rig2):
    n = int(5.0 / rig2.sample_time_s)
    exp = _open(rig2, np.full(n, 5.0))
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


def test_external_leak_lets_the_chamber_relax_to_atmosphere(rig1):
    n = int(3.0 / rig1.sample_time_s)
    leaky = simulate(rig1, _open(rig1, np.full(n, 5.0)),
                     [make_effect("leakage", kind="external", chamber="b", conductance_kg_per_s_Pa=2e-9)], noise_scale=0)
    p_b = leaky.state("pressure_b_Pa")
    assert p_b[-1] < p_b[0] - 0.5 * (p_b[0] - rig1["atmosphere_Pa"])


def test_deadband_stops_motion_for_small_commands(rig2):
    d = 0.4
    n = int(1.0 / rig2.sample_time_s)
    small = _open(rig2, np.full(n, 5.0 + 0.8 * d))
    nominal = simulate(rig2, small, noise_scale=0)
    banded = simulate(rig2, small, [make_effect("valve_deadband", deadband_V=d)], noise_scale=0)
    assert np.ptp(nominal.state("position_m")) > 0.01
    assert np.ptp(banded.state("position_m")) < 1e-9
    # a large command still gets full opening at full command
    model = ActuatorModel([make_effect("valve_deadband", deadband_V=d)])
    x = model.initial_state(rig2, 0.1)
    opening = np.asarray(model.outputs(x, 10.0, model.param_vector(rig2))).ravel()[0]
    assert opening == pytest.approx(1.0)


def test_valve_offset_drifts_at_nominal_null(rig1):
    n = int(0.5 / rig1.sample_time_s)
    exp = _open(rig1, np.full(n, 5.0))
    drift = simulate(rig1, exp, [make_effect("valve_offset", offset_V=-0.2)], noise_scale=0)
    assert drift.state("position_m")[-1] - drift.state("position_m")[0] > 2e-3  # true null below 5 V: extends


def test_valve_dynamics_lag_the_opening_and_vanish_when_fast(rig1):
    rng = np.random.default_rng(3)
    u = 5.0 + np.repeat(rng.choice([-1.5, 1.5], 40), 25)
    u = np.concatenate([u, np.full(400, u[-1])])  # hold the last command until the spool settles
    exp = _open(rig1, u)
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


def test_transport_delay_shifts_the_response_by_the_delay(rig2):
    # doublets after a rest at null, so the delayed valve has seen the same history
    u = np.concatenate([np.full(10, 5.0), 5.0 + np.repeat(np.tile([1.0, -1.0], 15), 20)])
    exp = _open(rig2, u)
    nominal = simulate(rig2, exp, noise_scale=0)
    m = 3
    delayed = simulate(rig2, exp, [make_effect("transport_delay", delay_s=m * rig2.sample_time_s)], noise_scale=0)
    shifted = nominal.state("position_m")[:-m]
    assert np.max(np.abs(delayed.state("position_m")[m:] - shifted)) < 1e-6
    # a fractional delay lies between the neighbouring whole-sample delays in timing
    half = simulate(rig2, exp, [make_effect("transport_delay", delay_s=2.5 * rig2.sample_time_s)], noise_scale=0)
    x_half = half.state("position_m")
    assert np.max(np.abs(x_half[3:] - nominal.state("position_m")[:-3])) > 1e-5


def test_heat_transfer_relaxes_chamber_temperature_after_a_fast_move(rig2):
    n_move, n_rest = int(0.15 / rig2.sample_time_s), int(1.5 / rig2.sample_time_s)
    u = np.concatenate([np.full(n_move, 8.0), np.full(n_rest, 5.0)])
    exp = _open(rig2, u, position=0.05)
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


def test_supply_droops_during_long_moves_and_recovers(rig2):
    n_move, n_rest = int(0.4 / rig2.sample_time_s), int(2.0 / rig2.sample_time_s)
    u = np.concatenate([np.full(n_move, 10.0), np.full(n_rest, 5.0)])
    eff = make_effect("supply_pressure_droop", supply_volume_m3=2e-4, supply_conductance_m3_per_s_Pa=5e-9,
                      regulator_Pa=rig2["supply_Pa"])
    sim = simulate(rig2, _open(rig2, u, position=0.02), [eff], noise_scale=0)
    supply = sim.state("supply_pressure_Pa")
    assert supply.min() < 0.9 * rig2["supply_Pa"]
    assert supply[-1] == pytest.approx(rig2["supply_Pa"], rel=1e-3)
    nominal = simulate(rig2, _open(rig2, u, position=0.02), noise_scale=0)
    k = np.argmax(nominal.state("position_m") > 0.2)
    assert sim.state("position_m")[k] < nominal.state("position_m")[k]  # slower under droop


def test_external_load_adds_its_force(rig1):
    eff = make_effect("external_load", force_N=-20.0, stiffness_N_per_m=300.0)
    model, nominal = ActuatorModel([eff]), ActuatorModel()
    x = np.array([0.04, 0.0, 5e5, 5e5])
    a = float(model.rhs(x, 5.0, model.param_vector(rig1))[1])
    a0 = float(nominal.rhs(x, 5.0, nominal.param_vector(rig1))[1])
    assert (a - a0) * rig1["moving_mass_kg"] == pytest.approx(-20.0 - 300.0 * 0.04)


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


def test_pressure_dependent_friction_moves_the_piston_and_vanishes_at_zero_coefficient(rig2):
    """Along a simulated run the seal friction is the law at the simulated |p_A - p_B| (below the reference
    level while gliding, above it when accelerating), the position departs from the nominal model's by far
    more than sensor noise, and k = 0 is the nominal model to the solver's accuracy."""
    u = np.concatenate([np.full(10, 5.0), 5.0 + np.repeat(np.tile([2.0, -2.0], 3), 20), np.full(20, 5.0)])
    exp = _open(rig2, u)
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
