"""Which parameters a fit frees, their scales and their physical bounds.

A free parameter enters the optimiser as ``theta = value / scale`` (the scale
is its starting value, or a typical magnitude when it starts at zero), so that
every decision variable is of order one.  Bounds are physical: positive where
the physics needs it (within a factor of 50 of the start: a real rig differs
from its data sheet by tens of percent, not by orders of magnitude), the
critical pressure ratio in (0.05, 0.95), effect parameters in the ranges that
keep the effect physical.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import FitError
from ..model.effects import EFFECTS, POSITIVE_NEAR_START

__all__ = ["DEFAULT_FREE", "EFFECT_FREE", "parameter_scale", "parameter_bounds", "check_free", "clip_inside"]

#: the nominal model's free parameters (``shared/spec/diagnosis.md``)
DEFAULT_FREE = ("valve_sonic_conductance_m3_per_s_Pa", "valve_critical_pressure_ratio",
                "friction_static_N", "friction_coulomb_N", "friction_stribeck_velocity_m_per_s",
                "friction_viscous_N_s_per_m", "moving_mass_kg")

#: the parameters an effect adds to the free set when it is switched on in a fit (each effect's ``fit_free``,
#: in registry order)
EFFECT_FREE = {name: tuple(f"{name}.{key}" for key in cls.fit_free) for name, cls in EFFECTS.items()}

#: parameters found by a search over a grid instead of by gradient (each effect's ``searched``: they move
#: command switch times)
SEARCHED = tuple(f"{name}.{key}" for name, cls in EFFECTS.items() for key in cls.searched)

#: (typical magnitude, lower, upper) in SI units; None: from the starting value.  The nominal model's rows
#: here; each effect's rows (``EFFECT.PARAM``) are its ``fit_scale``
_NOMINAL_TABLE = {
    "valve_critical_pressure_ratio": (0.3, 0.05, 0.95),
    "friction_static_N": (None, 0.0, None),
    "friction_coulomb_N": (None, 0.0, None),
    "friction_viscous_N_s_per_m": (None, 0.0, None),
}
_TABLE = {**_NOMINAL_TABLE,
          **{f"{name}.{key}": row for name, cls in EFFECTS.items() for key, row in cls.fit_scale.items()}}


def parameter_scale(name: str, start: float) -> float:
    """Typical magnitude of a parameter: the table's, else the starting value's."""
    scale = _TABLE.get(name, (None,))[0]
    if scale is None:
        scale = abs(start) if start != 0 else 1.0
    return float(scale)


def parameter_bounds(name: str, start: float) -> tuple[float, float]:
    """Physical ``(lower, upper)`` bounds in SI units."""
    typical, lo, hi = _TABLE.get(name, POSITIVE_NEAR_START)
    # never narrower than the typical magnitude: an effect starts where diagnosis's screening left it,
    # often near zero, and bounds that followed the start down would exclude the true value
    magnitude = max(abs(start), typical or 0.0) or parameter_scale(name, start)
    if lo == "pos":  # positive parameters: within a factor 50 of the start
        lo, hi = magnitude / 50.0, magnitude * 50.0
    if lo is None:
        lo = -50.0 * magnitude
    if hi is None:
        hi = 50.0 * magnitude
    lo, hi = _within_effect_range(name, lo, hi, magnitude)
    return float(lo), float(hi)


def _within_effect_range(name: str, lo: float, hi: float, magnitude: float) -> tuple[float, float]:
    """``(lo, hi)`` narrowed to the effect's own physical range (:attr:`Effect.ranges`) for an
    ``EFFECT.PARAM`` name: a fitted value must make a valid effect (a negative spring stiffness would end
    a diagnosis refit with "stiffness_N_per_m must be >= 0")."""
    effect, _, key = name.partition(".")
    if not key:
        return lo, hi
    cls = EFFECTS.get(effect)
    bounds = getattr(cls, "ranges", {}).get(key) if cls is not None else None
    if bounds is None:
        return lo, hi
    low, high, low_included, high_included = bounds
    # an open end stays a hair inside: IPOPT may end on a bound
    if lo <= low:
        lo = low if low_included else low + 1e-9 * magnitude
    if hi >= high:
        hi = high if high_included else high - 1e-9 * magnitude
    return lo, hi


def check_free(names: Sequence[str], param_names: Sequence[str]) -> None:
    """Refuse free parameters the model does not have, or listed twice.  A parameter the data sheet
    marks as known may be freed on request: a user may doubt a data-sheet value.

    An ``EFFECT.PARAM`` name is refused for what is wrong with it: an effect that does not exist, an
    effect that is not switched on, or a parameter the switched-on effect does not have."""
    for name in names:
        if name not in param_names:
            effect, dot, key = name.partition(".")
            if dot:
                if effect not in EFFECTS:
                    raise FitError(f"--free {name}: no effect {effect!r}; expected EFFECT.PARAM with an effect "
                                   f"among {', '.join(EFFECTS)}")
                own = [p for p in param_names if p.startswith(effect + ".")]
                if own:
                    raise FitError(f"--free {name}: {effect} has no parameter {key!r}; expected one of "
                                   f"{', '.join(own)}")
                raise FitError(f"--free {name}: the effect {effect!r} is not switched on; "
                               f"add --effect {effect}")
            raise FitError(f"--free {name}: not a parameter of this model; expected a rig parameter "
                           f"such as {', '.join(DEFAULT_FREE[:3])} or EFFECT.PARAM of a switched-on effect")
    if len(set(names)) != len(names):
        raise FitError(f"--free lists a parameter twice: {', '.join(names)}")


def clip_inside(v, lower, upper):
    """``v`` clipped to strictly inside the finite bounds ``lower .. upper`` (a relative 1e-12 in from each);
    an infinite bound (spool and temperature states) stays infinite.  The optimisers' start points."""
    with np.errstate(invalid="ignore"):   # np.where evaluates both branches: inf - inf is NaN there
        inner_lower = np.where(np.isfinite(lower), lower + 1e-12 * np.abs(lower), lower)
        inner_upper = np.where(np.isfinite(upper), upper - 1e-12 * np.abs(upper), upper)
    return np.clip(v, inner_lower, inner_upper)
