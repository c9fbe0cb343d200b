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

__all__ = ["Effect", "EFFECTS", "make_effect", "parse_effect_text", "seal_pressure_factor"]


class Effect:
    """Base class: an optional part of the actuator model, off unless listed."""

    name = ""
    description = ""
    parameters: Mapping[str, float] = {}
    options: Mapping[str, tuple[str, ...]] = {}
    states: tuple[str, ...] = ()
    #: physical range of a parameter, ``name: (low, high, low_included, high_included)``; any
    #: parameter not listed must only be finite
    ranges: Mapping[str, tuple[float, float, bool, bool]] = {}

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
        for key, value in self.values.items():
            if not in_range(value, self.ranges.get(key)):
                raise PneusimError(f"effect {self.name}: parameter {key} must be "
                                   f"{range_words(self.ranges.get(key))}, got {value!r}")

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


_INF = math.inf
POSITIVE = (0.0, _INF, False, False)
NON_NEGATIVE = (0.0, _INF, True, False)


def in_range(value: float, bounds) -> bool:
    """True when ``value`` is finite and inside ``bounds`` (``(low, high, low_included, high_included)``)."""
    if not math.isfinite(value):
        return False
    if bounds is None:
        return True
    lo, hi, lo_in, hi_in = bounds
    return (value >= lo if lo_in else value > lo) and (value <= hi if hi_in else value < hi)


def range_words(bounds) -> str:
    """``bounds`` in words: ``'a finite number'``, ``'>= 0'``, ``'in (0, 1]'``."""
    if bounds is None:
        return "a finite number"
    lo, hi, lo_in, hi_in = bounds
    if hi == _INF:
        return f"{'>=' if lo_in else '>'} {lo:g}"
    return f"in {'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"


class Leakage(Effect):
    name = "leakage"
    description = "laminar air flow across the piston seal (A<->B) or from a chamber to atmosphere"
    parameters = {"conductance_kg_per_s_Pa": 1.0e-9}
    ranges = {"conductance_kg_per_s_Pa": NON_NEGATIVE}
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
    ranges = {"deadband_V": NON_NEGATIVE}

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
    ranges = {"natural_frequency_Hz": POSITIVE, "damping": POSITIVE}
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
    #: at most 10 s: tubing and DAQ latency are milliseconds, and the sample loop holds the delayed commands
    #: in a buffer of delay / sample time values (a delay of 1e9 s asked for 7 TiB)
    ranges = {"delay_s": (0.0, 10.0, True, True)}

    def command_delay_s(self):
        return self.values["delay_s"]


class HeatTransfer(Effect):
    name = "heat_transfer"
    description = "heat exchange between chamber air and walls (not adiabatic)"
    parameters = {"time_constant_s": 0.1, "wall_temperature_K": 293.15}
    ranges = {"time_constant_s": POSITIVE, "wall_temperature_K": POSITIVE}
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
    ranges = {"retract_factor": POSITIVE}

    def friction_factor(self, ctx):
        return ca.if_else(ctx.v < 0, self.p(ctx, "retract_factor"), 1.0)


class SupplyPressureDroop(Effect):
    name = "supply_pressure_droop"
    description = "valve fed from a volume refilled from a regulator through a restriction"
    parameters = {"supply_volume_m3": 2.0e-4, "supply_conductance_m3_per_s_Pa": 5.0e-9,
                  "regulator_Pa": 701325.0}
    ranges = {"supply_volume_m3": POSITIVE, "supply_conductance_m3_per_s_Pa": POSITIVE, "regulator_Pa": POSITIVE}
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
    ranges = {"stiffness_N_per_m": NON_NEGATIVE}
    options = {"kind": ("constant", "spring")}

    def external_force_N(self, ctx):
        return self.p(ctx, "force_N") - self.p(ctx, "stiffness_N_per_m") * ctx.x_pos


#: Pa: |p_A - p_B| is smoothed as d tanh(d / this): within 0.1 Pa of |d| above 6 kPa, at most 0.28 of this below
PRESSURE_SMOOTHING_PA = 1000.0


def seal_pressure_factor(difference_Pa, pressure_coefficient, reference_difference_Pa, supply_gauge_Pa,
                         tanh=ca.tanh):
    """Factor on the static and Coulomb levels of :class:`PressureDependentFriction`, dimensionless.

    ``(1 + k |d| / S) / (1 + k d_ref / S)`` with ``d = p_A - p_B`` (Pa), ``|d|`` smoothed as
    ``d tanh(d / PRESSURE_SMOOTHING_PA)``, ``S`` the supply gauge pressure (Pa).  Works on CasADi
    symbols, and on NumPy arrays with ``tanh=numpy.tanh``.
    """
    magnitude = difference_Pa * tanh(difference_Pa / PRESSURE_SMOOTHING_PA)
    return ((1.0 + pressure_coefficient * magnitude / supply_gauge_Pa)
            / (1.0 + pressure_coefficient * reference_difference_Pa / supply_gauge_Pa))


class PressureDependentFriction(Effect):
    """Seal friction that grows with the pressure difference across the piston seal.

    The law of the vocabulary (``shared/spec/diagnosis.md``): static and Coulomb
    levels are ``F_0 (1 + k |p_A - p_B| / S)``, with ``F_0`` the level at zero
    difference, ``k = pressure_coefficient`` (dimensionless) and ``S`` the supply
    gauge pressure ``supply_Pa - atmosphere_Pa`` of the rig (Pa).  Viscous
    friction and the Stribeck velocity are unchanged.

    Parameterisation: the rig's ``friction_static_N`` and ``friction_coulomb_N``
    stay the levels *at* ``reference_difference_Pa`` (``d_ref``), so the effect
    multiplies them by ``(1 + k |d| / S) / (1 + k d_ref / S)``.  A constant-friction
    (nominal) fit finds about the level at the pressure differences the recording
    runs at; with ``d_ref`` there (default 50 kPa: a rig at rest near mid-stroke
    holds 30-45 kPa across its seal, and moves start from there), the nominal
    estimates are the right starting values when the effect is switched on, the
    levels keep their meaning, and ``k`` is nearly uncorrelated with them.  With
    the levels at zero difference instead, switching the effect on would move
    the levels by a factor ``1 + k d_ref / S`` and tie them to ``k``.  ``d_ref``
    is a choice of reference, not a property of the seal: do not free it in a fit
    (it is degenerate with the levels); set it, e.g., to the typical ``|p_A - p_B|``
    of the recording.  ``k = 0`` is the nominal model exactly.

    ``|p_A - p_B|`` is smoothed (:data:`PRESSURE_SMOOTHING_PA`) so that the
    right-hand side stays differentiable for CVODE's Newton iteration and the
    fit's sensitivities, like the ``tanh`` of the friction through zero velocity.
    """

    name = "pressure_dependent_friction"
    description = ("static and Coulomb friction that grow with |p_A - p_B|: "
                   "level(d) = level(d_ref) (1 + k|d|/S) / (1 + k d_ref/S), S the supply gauge pressure")
    parameters = {"pressure_coefficient": 2.0, "reference_difference_Pa": 5.0e4}
    ranges = {"pressure_coefficient": NON_NEGATIVE, "reference_difference_Pa": NON_NEGATIVE}

    def friction_factor(self, ctx):
        return seal_pressure_factor(ctx.p_a - ctx.p_b, self.p(ctx, "pressure_coefficient"),
                                    self.p(ctx, "reference_difference_Pa"),
                                    ctx.param("supply_Pa") - ctx.param("atmosphere_Pa"))


EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in (
    Leakage, ValveDeadband, ValveOffset, ValveDynamics, TransportDelay, HeatTransfer,
    FrictionAsymmetry, SupplyPressureDroop, ExternalLoad, PressureDependentFriction)}


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
