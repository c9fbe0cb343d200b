"""Work in progress (issue 5, not wired to the command line or tested yet).

Which parameters a fit frees, their scales (typical values) and physical bounds.

A free parameter enters the optimiser as ``theta = value / scale`` so that
every decision variable is of order one.  Bounds are physical: positive where
the physics needs it, the critical pressure ratio in (0.05, 0.95).
"""

from __future__ import annotations

from ..errors import FitError
from ..rig import Rig

__all__ = ["DEFAULT_FREE", "parameter_scale", "parameter_bounds", "UNFITTABLE"]

#: the nominal model's free parameters (``shared/spec/diagnosis.md``)
DEFAULT_FREE = ("valve_sonic_conductance_m3_per_s_Pa", "valve_critical_pressure_ratio",
                "friction_static_N", "friction_coulomb_N", "friction_stribeck_velocity_m_per_s",
                "friction_viscous_N_s_per_m", "moving_mass_kg")

#: parameters whose effect is not inside the ODE (handled by the command schedule)
UNFITTABLE = {"transport_delay.delay_s": "the transport delay shifts the command schedule outside the "
                                         "CasADi model, so it cannot be fitted by gradient; "
                                         "fix it with --effect transport_delay:delay_s=VALUE "
                                         "(supported only as a whole number of samples)"}

#: (scale, lower, upper) in SI units; None: derived from the starting value
_TABLE = {
    "valve_critical_pressure_ratio": (0.3, 0.05, 0.95),
    "friction_static_N": (None, 0.0, None),
    "friction_coulomb_N": (None, 0.0, None),
    "friction_viscous_N_s_per_m": (None, 0.0, None),
    "valve_deadband.deadband_V": (0.2, 0.0, 2.5),
    "valve_offset.offset_V": (0.1, -2.0, 2.0),
    "leakage.conductance_kg_per_s_Pa": (1e-9, 0.0, None),
    "external_load.force_N": (10.0, None, None),
    "external_load.stiffness_N_per_m": (100.0, None, None),
    "friction_asymmetry.retract_factor": (1.0, 0.05, 20.0),
    "valve_dynamics.damping": (0.7, 0.05, 5.0),
    "heat_transfer.wall_temperature_K": (293.15, 200.0, 400.0),
}


def parameter_scale(name: str, start: float) -> float:
    """Typical magnitude of a parameter (its starting value unless the table says otherwise)."""
    scale = _TABLE.get(name, (None,))[0]
    if scale is None:
        scale = abs(start) if start != 0 else 1.0
    return float(scale)


def parameter_bounds(name: str, start: float) -> tuple[float, float]:
    """Physical (lower, upper) bounds in SI units."""
    if name in UNFITTABLE:
        raise FitError(f"cannot fit {name}: {UNFITTABLE[name]}")
    _, lo, hi = _TABLE.get(name, (None, "pos", "pos"))
    mag = abs(start) if start != 0 else 1.0
    if lo == "pos":  # positive parameters: within a factor 50 of the start
        lo, hi = mag / 50.0, mag * 50.0
    if lo is None:
        lo = -50.0 * mag
    if hi is None:
        hi = 50.0 * mag
    return float(lo), float(hi)


def check_free(names, param_names, rig: Rig) -> None:
    for name in names:
        if name in UNFITTABLE:
            raise FitError(f"cannot fit {name}: {UNFITTABLE[name]}")
        if name not in param_names:
            effect = name.partition(".")[0] if "." in name else None
            hint = (f"switch the effect on with --effect {effect}" if effect else
                    "expected a rig parameter of rigs.toml such as " + ", ".join(DEFAULT_FREE[:3]))
            raise FitError(f"--free {name!r} is not a parameter of this model; {hint}")
