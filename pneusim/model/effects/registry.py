"""The registry of effects: the one ordered list the model, the fit and the diagnosis read.

The order matters: the diagnosis's candidate list and the fit's parameter vectors follow it.  To add
an effect, write its module (``docs/adding-an-effect.md``) and add its class to :data:`EFFECTS` here.
"""

from __future__ import annotations

from ...errors import PneusimError
from .base import LOOK_ALIKE_FAMILIES, Effect
from .external_load import ExternalLoad
from .friction_asymmetry import FrictionAsymmetry
from .heat_transfer import HeatTransfer
from .leakage import Leakage
from .pressure_dependent_friction import PressureDependentFriction
from .supply_pressure_droop import SupplyPressureDroop
from .transport_delay import TransportDelay
from .valve_deadband import ValveDeadband
from .valve_dynamics import ValveDynamics
from .valve_offset import ValveOffset

__all__ = ["EFFECTS", "make_effect", "parse_effect_text", "effect_class", "families"]

#: every effect of the vocabulary by name, in the order of the candidate list and the parameter vectors
EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in (
    Leakage, ValveDeadband, ValveOffset, ValveDynamics, TransportDelay, HeatTransfer,
    FrictionAsymmetry, SupplyPressureDroop, ExternalLoad, PressureDependentFriction)}


def effect_class(name: str) -> type[Effect]:
    """The effect class of a vocabulary name; an unknown name is refused with the known ones."""
    if name not in EFFECTS:
        raise PneusimError(f"unknown effect {name!r}; expected one of: {', '.join(EFFECTS)}")
    return EFFECTS[name]


def make_effect(name: str, **values) -> Effect:
    """Build an effect by its vocabulary name, e.g. ``make_effect('valve_deadband', deadband_V=0.3)``."""
    return effect_class(name)(**values)


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


def families() -> dict[str, tuple[str, ...]]:
    """``{family: its effects}`` of :data:`~.base.LOOK_ALIKE_FAMILIES`, each in registry order."""
    return {family: tuple(n for n, cls in EFFECTS.items() if cls.family == family)
            for family in LOOK_ALIKE_FAMILIES}
