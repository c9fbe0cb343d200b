"""The physics of a valve-driven pneumatic cylinder, written once in CasADi."""

from .actuator import ActuatorModel, BASE_STATES, RIG_PARAMETERS
from .effects import EFFECTS, Effect, make_effect, parse_effect_text

__all__ = ["ActuatorModel", "BASE_STATES", "RIG_PARAMETERS", "EFFECTS", "Effect", "make_effect",
           "parse_effect_text"]
