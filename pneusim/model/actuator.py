"""The actuator model: valve, chambers and piston wired together, plus optional effects.

This is the one definition of the physics.  It is written symbolically in
CasADi; the simulator takes its right-hand side and Jacobian (compiled to C),
and the fitter takes the same graph with the parameters as symbols.

States (in this order, then each effect's own states):
``position_m``, ``velocity_m_per_s``, ``pressure_a_Pa``, ``pressure_b_Pa``.

Inputs: the valve command as the valve sees it, V.  Parameters: a vector in
the order of :attr:`ActuatorModel.param_names` (rig parameters by their rig
file names, effect parameters as ``EFFECT.PARAM``).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Iterable, Mapping, Sequence

import casadi as ca
import numpy as np

from ..errors import PneusimError
from ..rig import Rig
from . import chamber, piston, valve
from .effects import Effect

__all__ = ["ActuatorModel", "BASE_STATES", "RIG_PARAMETERS"]

BASE_STATES = ("position_m", "velocity_m_per_s", "pressure_a_Pa", "pressure_b_Pa")

#: rig parameters that enter the equations, in parameter-vector order
RIG_PARAMETERS = (
    "bore_m", "rod_m", "stroke_m", "supply_Pa", "exhaust_Pa", "atmosphere_Pa", "supply_temperature_K",
    "valve_null_V", "moving_mass_kg", "dead_volume_a_m3", "dead_volume_b_m3",
    "valve_sonic_conductance_m3_per_s_Pa", "valve_critical_pressure_ratio",
    "friction_static_N", "friction_coulomb_N", "friction_stribeck_velocity_m_per_s",
    "friction_viscous_N_s_per_m", "friction_smoothing_velocity_m_per_s",
    "endstop_stiffness_N_per_m", "endstop_damping_N_s_per_m",
)

#: signals available from :meth:`ActuatorModel.outputs`, besides the states
OUTPUT_NAMES = ("valve_opening", "supply_pressure_Pa", "flow_into_a_kg_per_s", "flow_into_b_kg_per_s",
                "flow_from_supply_kg_per_s", "friction_force_N", "end_stop_force_N",
                "pressure_force_N", "external_force_N", "temperature_a_K", "temperature_b_K",
                "enthalpy_into_a_kg_K_per_s", "enthalpy_into_b_kg_K_per_s")


class ActuatorModel:
    """Symbolic model of a valve-driven double-acting cylinder.

    Parameters
    ----------
    effects : sequence of Effect
        Optional effects to include (at most one of each kind).

    Attributes
    ----------
    state_names : tuple of str
    param_names : tuple of str
    rhs : casadi.Function
        ``rhs(x[n], u[1], p[np]) -> xdot[n]``.
    jac : casadi.Function
        ``jac(x, u, p) -> d xdot / d x`` (dense n x n).
    outputs : casadi.Function
        ``outputs(x, u, p) -> y[len(output_names)]``.
    """

    def __init__(self, effects: Sequence[Effect] = ()):
        names = [e.name for e in effects]
        if len(set(names)) != len(names):
            raise PneusimError(f"each effect may be listed once; got {', '.join(names)}")
        self.effects = tuple(effects)
        self.state_names = BASE_STATES + tuple(s for e in self.effects for s in e.states)
        self.param_names = RIG_PARAMETERS + tuple(k for e in self.effects for k in e.qualified())
        self.output_names = OUTPUT_NAMES
        self._build()

    # ------------------------------------------------------------------ build
    def _build(self):
        x = ca.SX.sym("x", len(self.state_names))
        u = ca.SX.sym("u", 1)
        p = ca.SX.sym("p", len(self.param_names))
        index = {name: i for i, name in enumerate(self.param_names)}
        xs = {name: x[i] for i, name in enumerate(self.state_names)}
        ctx = SimpleNamespace(x=xs, param=lambda key: p[index[key]])
        xdot, out = self._equations(ctx, u[0])
        self.x_sym, self.u_sym, self.p_sym = x, u, p
        self.xdot_sym = ca.vertcat(*[xdot[s] for s in self.state_names])
        self.rhs = ca.Function("pneusim_rhs", [x, u, p], [self.xdot_sym], ["x", "u", "p"], ["xdot"])
        self.jac = ca.Function("pneusim_jac", [x, u, p], [ca.densify(ca.jacobian(self.xdot_sym, x))],
                               ["x", "u", "p"], ["jac"])
        self.outputs = ca.Function("pneusim_outputs", [x, u, p],
                                   [ca.vertcat(*[out[k] for k in self.output_names])], ["x", "u", "p"], ["y"])

    def _equations(self, ctx, command_V):
        P = ctx.param
        effects = self.effects
        ctx.x_pos = pos = ctx.x["position_m"]
        ctx.v = vel = ctx.x["velocity_m_per_s"]
        ctx.p_a, ctx.p_b = ctx.x["pressure_a_Pa"], ctx.x["pressure_b_Pa"]
        t_supply = P("supply_temperature_K")
        ctx.T_a = ctx.x.get("temperature_a_K", t_supply)
        ctx.T_b = ctx.x.get("temperature_b_K", t_supply)

        # valve: command -> opening (offset, dead band, spool dynamics)
        null_V = P("valve_null_V")
        for e in effects:
            null_V = e.valve_null_V(ctx, null_V)
        deadbands = [e.deadband_V(ctx) for e in effects if not _is_zero(e.deadband_V(ctx))]
        deadband_V = deadbands[0] if deadbands else 0.0
        opening = valve.opening_from_command(command_V, null_V, deadband_V)
        for e in effects:
            opening = e.opening(ctx, opening)
        supplies = [e.supply_Pa(ctx) for e in effects if e.supply_Pa(ctx) is not None]
        supply = supplies[0] if supplies else P("supply_Pa")
        ctx.supply = supply

        # ISO 6358 flows through the four metering edges
        C, b = P("valve_sonic_conductance_m3_per_s_Pa"), P("valve_critical_pressure_ratio")
        exhaust = P("exhaust_Pa")
        open_pos, open_neg = ca.fmax(opening, 0.0), ca.fmax(-opening, 0.0)
        q_sa = valve.iso6358_mass_flow(C * open_pos, b, supply, ctx.p_a, t_supply, ctx.T_a)
        q_be = valve.iso6358_mass_flow(C * open_pos, b, ctx.p_b, exhaust, ctx.T_b, t_supply)
        q_sb = valve.iso6358_mass_flow(C * open_neg, b, supply, ctx.p_b, t_supply, ctx.T_b)
        q_ae = valve.iso6358_mass_flow(C * open_neg, b, ctx.p_a, exhaust, ctx.T_a, t_supply)
        ctx.supply_draw = q_sa + q_sb

        def upstream(q, t_from, t_chamber):
            return q * ca.if_else(q >= 0, t_from, t_chamber)

        flows = {"a": [(q_sa, t_supply), (-q_ae, t_supply)], "b": [(q_sb, t_supply), (-q_be, t_supply)]}
        for e in effects:
            for which, q, t_in in e.extra_flows(ctx):
                flows[which].append((q, t_in))
        mass_in = {k: sum(q for q, _ in v) for k, v in flows.items()}
        t_ch = {"a": ctx.T_a, "b": ctx.T_b}
        enthalpy_in = {k: sum(upstream(q, t_in, t_ch[k]) for q, t_in in v) for k, v in flows.items()}

        # chambers
        area_a, area_b, area_rod = _areas(P)
        ctx.V_a, ctx.V_b, dV_a, dV_b = chamber.chamber_volumes_m3(
            pos, vel, P("stroke_m"), area_a, area_b, P("dead_volume_a_m3"), P("dead_volume_b_m3"))
        heat = (0.0, 0.0)
        for e in effects:
            rates = e.heat_rates_W(ctx)
            heat = rates if rates is not None else heat
        dp_a = chamber.pressure_rate(ctx.p_a, ctx.V_a, dV_a, enthalpy_in["a"], heat[0])
        dp_b = chamber.pressure_rate(ctx.p_b, ctx.V_b, dV_b, enthalpy_in["b"], heat[1])
        ctx.dT_a = chamber.temperature_rate(ctx.T_a, ctx.p_a, dp_a, ctx.V_a, dV_a, mass_in["a"])
        ctx.dT_b = chamber.temperature_rate(ctx.T_b, ctx.p_b, dp_b, ctx.V_b, dV_b, mass_in["b"])

        # piston
        factor = 1.0
        external = 0.0
        for e in effects:
            factor = factor * e.friction_factor(ctx)
            external = external + e.external_force_N(ctx)
        friction = piston.stribeck_friction_N(
            vel, factor * P("friction_static_N"), factor * P("friction_coulomb_N"),
            P("friction_stribeck_velocity_m_per_s"), P("friction_viscous_N_s_per_m"),
            P("friction_smoothing_velocity_m_per_s"))
        stops = piston.end_stop_force_N(pos, vel, P("stroke_m"), P("endstop_stiffness_N_per_m"),
                                        P("endstop_damping_N_s_per_m"))
        pressure_force = ctx.p_a * area_a - ctx.p_b * area_b - P("atmosphere_Pa") * area_rod
        accel = (pressure_force - friction + stops + external) / P("moving_mass_kg")

        xdot = {"position_m": vel, "velocity_m_per_s": accel, "pressure_a_Pa": dp_a, "pressure_b_Pa": dp_b}
        for e in effects:
            xdot.update(e.derivatives(ctx))
        out = {"valve_opening": opening, "supply_pressure_Pa": supply,
               "flow_into_a_kg_per_s": mass_in["a"], "flow_into_b_kg_per_s": mass_in["b"],
               "flow_from_supply_kg_per_s": ctx.supply_draw, "friction_force_N": friction,
               "end_stop_force_N": stops, "pressure_force_N": pressure_force, "external_force_N": external,
               "temperature_a_K": ctx.T_a, "temperature_b_K": ctx.T_b,
               "enthalpy_into_a_kg_K_per_s": enthalpy_in["a"], "enthalpy_into_b_kg_K_per_s": enthalpy_in["b"]}
        out = {k: v if isinstance(v, ca.SX) else ca.SX(v) for k, v in out.items()}
        return xdot, out

    # ----------------------------------------------------------- parameters
    def param_vector(self, rig: Rig) -> np.ndarray:
        """Numeric parameter vector from a rig and this model's effects."""
        values = self.param_dict(rig)
        return np.array([values[k] for k in self.param_names], dtype=float)

    def param_dict(self, rig: Rig) -> dict[str, float]:
        values = {k: float(rig.params[k]) for k in RIG_PARAMETERS}
        for e in self.effects:
            values.update(e.qualified())
        return values

    def command_delay_s(self) -> float:
        return float(sum(e.command_delay_s() for e in self.effects))

    def initial_state(self, rig: Rig, position_m: float, command_V: float | None = None,
                      params: Mapping[str, float] | None = None,
                      pressures_Pa: tuple[float, float] | None = None) -> np.ndarray:
        """A state at rest at ``position_m`` whose pressures balance the forces.

        Chamber B starts halfway between exhaust and supply and chamber A
        carries the rest of the load, so the piston does not jump at t = 0
        (the experiment's warm-up settles the remainder).
        """
        values = self.param_dict(rig) if params is None else dict(params)
        area_a, area_b, area_rod = _areas(lambda k: values[k])
        external = 0.0
        for e in self.effects:
            external = external + e.static_force_N(values, position_m)
        p_b = 0.5 * (values["supply_Pa"] + values["exhaust_Pa"])
        p_a = (p_b * area_b + values["atmosphere_Pa"] * area_rod - external) / area_a
        p_a = min(max(p_a, values["exhaust_Pa"]), values["supply_Pa"])
        if pressures_Pa is not None:
            p_a, p_b = (float(v) for v in pressures_Pa)
        state = {"position_m": position_m, "velocity_m_per_s": 0.0, "pressure_a_Pa": p_a, "pressure_b_Pa": p_b}
        opening0 = 0.0
        if command_V is not None:
            opening0 = float(np.clip((command_V - values["valve_null_V"]) / valve.FULL_OPENING_V, -1, 1))
        for e in self.effects:
            state.update(e.initial_state(values, opening0))
        return np.array([state[s] for s in self.state_names], dtype=float)

    def describe(self) -> str:
        effects = ", ".join(repr(e) for e in self.effects) or "none"
        return f"ActuatorModel(states={len(self.state_names)}, effects: {effects})"


def _areas(P):
    bore, rod = P("bore_m"), P("rod_m")
    area_a = np.pi / 4.0 * bore**2
    area_rod = np.pi / 4.0 * rod**2
    return area_a, area_a - area_rod, area_rod


def _is_zero(value) -> bool:
    return isinstance(value, (int, float)) and value == 0.0


def effect_names(effects: Iterable[Effect]) -> list[str]:
    return [e.name for e in effects]
