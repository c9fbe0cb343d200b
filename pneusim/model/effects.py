"""Optional effects: physics the nominal model leaves out (``shared/spec/diagnosis.md``).

Each effect is a small component with one contract: its numeric parameters
(``parameters``: name -> default, SI unit in the name), its structural options
(``options``: name -> allowed values), its extra states, and hooks that the
actuator assembly calls at fixed places.  A hook that an effect does not
override leaves the nominal physics unchanged, so any set of effects composes.

Parameters enter the CasADi graph as symbols named ``EFFECT.PARAM`` (for
example ``valve_deadband.deadband_V``), so a fit changes them without a rebuild.
"""

from __future__ import annotations

import math
from typing import Mapping

import casadi as ca

from ..errors import PneusimError
from . import chamber, valve

__all__ = ["Effect", "EFFECTS", "make_effect", "parse_effect_text"]


class Effect:
    """Base class: an optional part of the actuator model, off unless listed."""

    name = ""
    description = ""
    parameters: Mapping[str, float] = {}
    options: Mapping[str, tuple[str, ...]] = {}
    states: tuple[str, ...] = ()

    def __init__(self, **values):
        self.values = dict(self.parameters)
        self.option_values = {k: v[0] for k, v in self.options.items()}
        for key, value in values.items():
            if key in self.options:
                if value not in self.options[key]:
                    raise PneusimError(f"effect {self.name}: option {key} must be one of "
                                       f"{', '.join(self.options[key])}, got {value!r}")
                self.option_values[key] = value
            elif key in self.parameters:
                try:
                    self.values[key] = float(value)
                except (TypeError, ValueError):
                    raise PneusimError(f"effect {self.name}: parameter {key} must be a number, "
                                       f"got {value!r}") from None
            else:
                known = ", ".join(list(self.parameters) + list(self.options))
                raise PneusimError(f"effect {self.name} has no parameter {key!r}; expected one of: {known}")

    # --- identification ---------------------------------------------------
    def qualified(self) -> dict[str, float]:
        """``{EFFECT.PARAM: value}`` of the numeric parameters."""
        return {f"{self.name}.{k}": v for k, v in self.values.items()}

    def to_text(self) -> str:
        """The command-line form ``NAME:PARAM=VALUE,...`` that :func:`parse_effect_text` reads back."""
        items = {**self.option_values, **self.values}
        return self.name + ":" + ",".join(f"{k}={v!r}" if not isinstance(v, str) else f"{k}={v}"
                                          for k, v in items.items())

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in {**self.option_values, **self.values}.items())
        return f"{type(self).__name__}({args})"

    # --- hooks (ctx is the assembly context of actuator.py) -----------------
    def valve_null_V(self, ctx, null_V):
        return null_V

    def deadband_V(self, ctx):
        return 0.0

    def opening(self, ctx, commanded_opening):
        return commanded_opening

    def supply_Pa(self, ctx):
        return None

    def extra_flows(self, ctx):
        """List of ``(chamber 'a'|'b', signed mass flow into it kg/s, inflow temperature K)``."""
        return []

    def friction_factor(self, ctx):
        return 1.0

    def external_force_N(self, ctx):
        return 0.0

    def heat_rates_W(self, ctx):
        """``(Q_a, Q_b)`` into the chamber gas, or ``None`` for adiabatic chambers."""
        return None

    def derivatives(self, ctx) -> dict:
        """Rates of this effect's own states."""
        return {}

    def initial_state(self, params: Mapping[str, float], opening0: float) -> dict:
        return {}

    #: seconds by which the valve sees the command late (handled by the solver)
    def command_delay_s(self) -> float:
        return 0.0

    def p(self, ctx, key):
        return ctx.param(f"{self.name}.{key}")


class Leakage(Effect):
    name = "leakage"
    description = "laminar air flow across the piston seal (A<->B) or from a chamber to atmosphere"
    parameters = {"conductance_kg_per_s_Pa": 1.0e-9}
    options = {"kind": ("internal", "external"), "chamber": ("a", "b")}

    def extra_flows(self, ctx):
        g = self.p(ctx, "conductance_kg_per_s_Pa")
        if self.option_values["kind"] == "internal":
            q_ab = g * (ctx.p_a - ctx.p_b)
            t_up = ca.if_else(q_ab >= 0, ctx.T_a, ctx.T_b)
            return [("a", -q_ab, t_up), ("b", q_ab, t_up)]
        which = self.option_values["chamber"]
        p_ch, t_ch = (ctx.p_a, ctx.T_a) if which == "a" else (ctx.p_b, ctx.T_b)
        q_in = g * (ctx.param("atmosphere_Pa") - p_ch)
        t_in = ca.if_else(q_in >= 0, ctx.param("supply_temperature_K"), t_ch)
        return [(which, q_in, t_in)]


class ValveDeadband(Effect):
    name = "valve_deadband"
    description = "spool overlap: no flow while the command is within +-d of null"
    parameters = {"deadband_V": 0.2}

    def deadband_V(self, ctx):
        return self.p(ctx, "deadband_V")


class ValveOffset(Effect):
    name = "valve_offset"
    description = "the valve's true null is the nominal null plus an offset"
    parameters = {"offset_V": 0.1}

    def valve_null_V(self, ctx, null_V):
        return null_V + self.p(ctx, "offset_V")


class ValveDynamics(Effect):
    name = "valve_dynamics"
    description = "spool opening follows the commanded opening through a second-order lag"
    parameters = {"natural_frequency_Hz": 20.0, "damping": 0.7}
    states = ("spool_opening", "spool_rate_per_s")

    def opening(self, ctx, commanded_opening):
        ctx.commanded_opening = commanded_opening
        return ca.fmin(ca.fmax(ctx.x["spool_opening"], -1.0), 1.0)

    def derivatives(self, ctx):
        omega = 2.0 * math.pi * self.p(ctx, "natural_frequency_Hz")
        zeta = self.p(ctx, "damping")
        xv, rate = ctx.x["spool_opening"], ctx.x["spool_rate_per_s"]
        accel = omega**2 * (ctx.commanded_opening - xv) - 2.0 * zeta * omega * rate
        return {"spool_opening": rate, "spool_rate_per_s": accel}

    def initial_state(self, params, opening0):
        return {"spool_opening": opening0, "spool_rate_per_s": 0.0}


class TransportDelay(Effect):
    name = "transport_delay"
    description = "dead time between the command and the valve (tubing, DAQ latency)"
    parameters = {"delay_s": 0.01}

    def command_delay_s(self):
        return self.values["delay_s"]


class HeatTransfer(Effect):
    name = "heat_transfer"
    description = "heat exchange between chamber air and walls (not adiabatic)"
    parameters = {"time_constant_s": 0.1, "wall_temperature_K": 293.15}
    states = ("temperature_a_K", "temperature_b_K")

    def heat_rates_W(self, ctx):
        # tau is the time constant of the air temperature at constant volume:
        # m c_v dT/dt = Q = m c_v (T_w - T) / tau
        tau = self.p(ctx, "time_constant_s")
        t_wall = self.p(ctx, "wall_temperature_K")
        cv = chamber.R_AIR_J_PER_KG_K / (chamber.GAMMA - 1.0)
        mass_a = ctx.p_a * ctx.V_a / (chamber.R_AIR_J_PER_KG_K * ctx.T_a)
        mass_b = ctx.p_b * ctx.V_b / (chamber.R_AIR_J_PER_KG_K * ctx.T_b)
        return mass_a * cv * (t_wall - ctx.T_a) / tau, mass_b * cv * (t_wall - ctx.T_b) / tau

    def derivatives(self, ctx):
        return {"temperature_a_K": ctx.dT_a, "temperature_b_K": ctx.dT_b}

    def initial_state(self, params, opening0):
        t0 = params["heat_transfer.wall_temperature_K"]
        return {"temperature_a_K": t0, "temperature_b_K": t0}


class FrictionAsymmetry(Effect):
    name = "friction_asymmetry"
    description = "static and Coulomb friction multiplied by a factor when retracting"
    parameters = {"retract_factor": 1.5}

    def friction_factor(self, ctx):
        return ca.if_else(ctx.v < 0, self.p(ctx, "retract_factor"), 1.0)


class SupplyPressureDroop(Effect):
    name = "supply_pressure_droop"
    description = "valve fed from a volume refilled from a regulator through a restriction"
    parameters = {"supply_volume_m3": 2.0e-4, "supply_conductance_m3_per_s_Pa": 5.0e-9,
                  "regulator_Pa": 701325.0}
    states = ("supply_pressure_Pa",)

    def supply_Pa(self, ctx):
        return ctx.x["supply_pressure_Pa"]

    def derivatives(self, ctx):
        # isothermal supply volume: the line and receiver walls hold the air at supply temperature
        t_s = ctx.param("supply_temperature_K")
        refill = valve.iso6358_mass_flow(self.p(ctx, "supply_conductance_m3_per_s_Pa"),
                                         ctx.param("valve_critical_pressure_ratio"),
                                         self.p(ctx, "regulator_Pa"), ctx.supply, t_s, t_s)
        rate = chamber.R_AIR_J_PER_KG_K * t_s / self.p(ctx, "supply_volume_m3") * (refill - ctx.supply_draw)
        return {"supply_pressure_Pa": rate}

    def initial_state(self, params, opening0):
        return {"supply_pressure_Pa": params["supply_pressure_droop.regulator_Pa"]}


class ExternalLoad(Effect):
    name = "external_load"
    description = "a force not in the nominal model: constant (gravity, process load) plus a spring"
    parameters = {"force_N": 0.0, "stiffness_N_per_m": 0.0}
    options = {"kind": ("constant", "spring")}

    def external_force_N(self, ctx):
        return self.p(ctx, "force_N") - self.p(ctx, "stiffness_N_per_m") * ctx.x_pos


EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in (
    Leakage, ValveDeadband, ValveOffset, ValveDynamics, TransportDelay, HeatTransfer,
    FrictionAsymmetry, SupplyPressureDroop, ExternalLoad)}


def make_effect(name: str, **values) -> Effect:
    """Build an effect by its vocabulary name, e.g. ``make_effect('valve_deadband', deadband_V=0.3)``."""
    if name not in EFFECTS:
        raise PneusimError(f"unknown effect {name!r}; expected one of: {', '.join(EFFECTS)}")
    return EFFECTS[name](**values)


def parse_effect_text(text: str) -> Effect:
    """Parse the command-line form ``NAME:PARAM=VALUE,PARAM=VALUE`` (``NAME`` alone for defaults)."""
    name, _, rest = text.partition(":")
    values = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = item.partition("=")
        if not eq:
            raise PneusimError(f"--effect {text!r}: expected NAME:PARAM=VALUE[,PARAM=VALUE...], "
                               f"got {item!r} without '='")
        values[key.strip()] = value.strip()
    return make_effect(name.strip(), **values)
