"""Physical laws the model must obey: steady states, force balance, energy and mass balance."""

import numpy as np
import pytest

from pneusim.experiment import Experiment
from pneusim.model import ActuatorModel, make_effect
from pneusim.model.chamber import GAMMA, R_AIR_J_PER_KG_K, areas_m2
from pneusim.simulate import simulate


def _eval(fn, x, u, p):
    return np.asarray(fn(x, u, p)).ravel()


def test_rest_at_null_is_a_steady_state(rig):
    model = ActuatorModel()
    p = model.param_vector(rig)
    for position in (0.2 * rig.stroke_m, 0.5 * rig.stroke_m, 0.8 * rig.stroke_m):
        x0 = model.initial_state(rig, position)
        xdot = _eval(model.rhs, x0, rig["valve_null_V"], p)
        assert xdot[0] == 0.0
        assert abs(xdot[1]) < 1e-9  # force balance of the chosen pressures
        assert xdot[2] == 0.0 and xdot[3] == 0.0  # closed centre: no flow at null


def test_equal_atmospheric_pressures_at_null_are_steady(rig):
    model = ActuatorModel()
    p = model.param_vector(rig)
    atm = rig["atmosphere_Pa"]
    x0 = np.array([0.5 * rig.stroke_m, 0.0, atm, atm])
    assert np.allclose(_eval(model.rhs, x0, rig["valve_null_V"], p), 0.0, atol=1e-9)


def test_simulated_hold_at_null_does_not_move(rig):
    exp = Experiment("open", rig.sample_time_s, np.full(500, rig["valve_null_V"]), warmup_s=0.0,
                     initial_position_m=0.4 * rig.stroke_m)
    sim = simulate(rig, exp, noise_scale=0.0)
    assert np.ptp(sim.state("position_m")) < 1e-9
    assert np.ptp(sim.state("pressure_a_Pa")) < 1e-3


def test_force_balance_at_constant_velocity(rig2):
    """At steady velocity, pressure force equals the Stribeck friction of that velocity."""
    rig = rig2
    exp = Experiment("open", rig.sample_time_s, np.full(60, rig["valve_null_V"] + 0.6), warmup_s=0.0,
                     initial_position_m=0.05)
    sim = simulate(rig, exp, noise_scale=0.0)
    v = sim.state("velocity_m_per_s")
    k = np.argmax(v > 0) + 20
    assert v[k] > 0.05, "the piston must be moving"
    area_a, area_b, area_rod = areas_m2(rig["bore_m"], rig["rod_m"])
    x = sim.states[k]
    pressure_force = x[2] * area_a - x[3] * area_b - rig["atmosphere_Pa"] * area_rod
    fs, fc, vs, b = (rig["friction_static_N"], rig["friction_coulomb_N"],
                     rig["friction_stribeck_velocity_m_per_s"], rig["friction_viscous_N_s_per_m"])
    friction = (fc + (fs - fc) * np.exp(-(x[1] / vs) ** 2)) * np.tanh(x[1] / 1e-3) + b * x[1]
    accel = (v[k + 1] - v[k - 1]) / (2 * rig.sample_time_s)
    # near-constant velocity: the small remaining acceleration (from the trajectory, not the
    # model's right-hand side) accounts for the difference of pressure force and friction
    assert abs(rig["moving_mass_kg"] * accel) < 0.02 * friction
    assert pressure_force - friction == pytest.approx(rig["moving_mass_kg"] * accel, abs=0.002 * friction)


@pytest.mark.parametrize("command_V", [10.0, 0.0])
def test_end_stops_are_not_penetrated_more_than_half_a_millimetre(rig, command_V):
    exp = Experiment("open", rig.sample_time_s, np.full(int(1.5 / rig.sample_time_s), command_V), warmup_s=0.0,
                     initial_position_m=0.5 * rig.stroke_m)
    sim = simulate(rig, exp, noise_scale=0.0)
    pos = sim.state("position_m")
    assert pos.max() < rig.stroke_m + 5e-4 and pos.min() > -5e-4
    # and it did reach the stop it was driven into
    assert (pos.max() > rig.stroke_m - 1e-3) if command_V > 5 else (pos.min() < 1e-3)


def _dense_run(rig, effects, command, duration_s=0.4, dt=1e-4):
    fine = rig.with_params({"sample_time_s": dt})
    n = int(duration_s / dt)
    u = np.where(np.arange(n) * dt < duration_s / 2, command, 2 * rig["valve_null_V"] - command)
    exp = Experiment("open", dt, u, warmup_s=0.0, initial_position_m=0.5 * rig.stroke_m)
    sim = simulate(fine, exp, effects, noise_scale=0.0, rtol=1e-9)
    outputs = np.array([np.asarray(sim.model.outputs(x, uk, sim.params)).ravel() for x, uk in zip(sim.states, u)])
    return sim, outputs, u


def _cumtrapz(y, dt):
    return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * dt)])


def test_chamber_mass_equals_integrated_flows(rig2):
    """With chamber temperatures as states, m = pV/(RT) follows the integrated port flows."""
    effects = [make_effect("heat_transfer", time_constant_s=0.05)]
    sim, out, _ = _dense_run(rig2, effects, rig2["valve_null_V"] + 2.0)
    names = sim.model.output_names
    area_a, area_b, _ = areas_m2(rig2["bore_m"], rig2["rod_m"])
    x = sim.state("position_m")
    for ch, area, vol in (("a", area_a, rig2["dead_volume_a_m3"] + area_a * x),
                          ("b", area_b, rig2["dead_volume_b_m3"] + area_b * (rig2.stroke_m - x))):
        mass = sim.state(f"pressure_{ch}_Pa") * vol / (R_AIR_J_PER_KG_K * sim.state(f"temperature_{ch}_K"))
        flow = out[:, names.index(f"flow_into_{ch}_kg_per_s")]
        integrated = mass[0] + _cumtrapz(flow, 1e-4)
        change = np.ptp(mass)
        assert change > 0.2 * mass[0], "the test move must change the chamber mass noticeably"
        assert np.max(np.abs(mass - integrated)) < 2e-3 * change


def test_nominal_chambers_obey_the_first_law(rig1):
    """Adiabatic chambers: d(pV)/(gamma-1) = cp T_s m_dot dt - p dV (inflow and outflow at T_s)."""
    sim, out, _ = _dense_run(rig1, [], rig1["valve_null_V"] + 2.0)
    names = sim.model.output_names
    area_a, _, _ = areas_m2(rig1["bore_m"], rig1["rod_m"])
    x = sim.state("position_m")
    vol = rig1["dead_volume_a_m3"] + area_a * x
    p = sim.state("pressure_a_Pa")
    energy = p * vol / (GAMMA - 1.0)
    cp = GAMMA * R_AIR_J_PER_KG_K / (GAMMA - 1.0)
    enthalpy = cp * out[:, names.index("enthalpy_into_a_kg_K_per_s")]
    work = p * area_a * sim.state("velocity_m_per_s")
    integrated = energy[0] + _cumtrapz(enthalpy - work, 1e-4)
    assert np.ptp(energy) > 0.1 * energy[0]
    assert np.max(np.abs(energy - integrated)) < 2e-3 * np.ptp(energy)
