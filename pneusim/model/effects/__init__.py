"""Optional effects: physics the nominal model leaves out (``shared/spec/diagnosis.md``).

One module per effect holds everything about it (law, parameters, hooks, what a fit frees, how the
diagnosis screens it); :mod:`.base` holds the contract and :mod:`.registry` the ordered list.  See
``docs/adding-an-effect.md``.
"""

from .base import (EVIDENCE_PLOTS, LOOK_ALIKE_FAMILIES, NON_NEGATIVE, POSITIVE, POSITIVE_NEAR_START, REQUIRED, Effect,
                   ScreeningStart, in_range, missing_facts, number_text, range_words)
from .external_load import ExternalLoad
from .friction_asymmetry import FrictionAsymmetry
from .heat_transfer import HeatTransfer
from .leakage import Leakage
from .pressure_dependent_friction import PRESSURE_SMOOTHING_PA, PressureDependentFriction, seal_pressure_factor
from .registry import EFFECTS, effect_class, families, make_effect, parse_effect_text
from .supply_pressure_droop import SupplyPressureDroop
from .transport_delay import TransportDelay
from .valve_deadband import ValveDeadband
from .valve_dynamics import ValveDynamics
from .valve_offset import ValveOffset

__all__ = ["Effect", "EFFECTS", "make_effect", "parse_effect_text", "seal_pressure_factor", "effect_class",
           "families", "ScreeningStart", "LOOK_ALIKE_FAMILIES", "EVIDENCE_PLOTS", "REQUIRED", "missing_facts", "in_range",
           "range_words", "number_text", "POSITIVE", "NON_NEGATIVE", "POSITIVE_NEAR_START",
           "PRESSURE_SMOOTHING_PA", "Leakage", "ValveDeadband", "ValveOffset", "ValveDynamics",
           "TransportDelay", "HeatTransfer", "FrictionAsymmetry", "SupplyPressureDroop", "ExternalLoad",
           "PressureDependentFriction"]
