"""Rigs as data: a rig file is a TOML data sheet of named SI parameters.

A rig file has the sections of ``shared/spec/rigs.toml`` (``[known]`` and
``[typical]``) plus ``[model]`` (numerical constants of the model such as the
end-stop stiffness) and ``[sensors]`` (noise and converter resolution).  The
parameter names carry their unit and are the names used everywhere: rig files,
``--param NAME=VALUE``, fit results and JSON.

The rigs of the two source papers ship with the package (``pneusim/rigs/``);
a user copies one and edits it to describe their own rig.
"""

from __future__ import annotations

import dataclasses

from pathlib import Path
from typing import Mapping

from .errors import InputFileError, PneusimError
from .tomlfile import read_toml

__all__ = ["Rig", "load_rig", "known_rig_names", "known_stroke_m", "RIG_SECTIONS"]

RIG_DIR = Path(__file__).with_name("rigs")
RIG_SECTIONS = ("known", "typical", "model", "sensors")

#: parameters every rig file must define, by section
REQUIRED = {
    "known": ("bore_m", "rod_m", "stroke_m", "supply_Pa", "exhaust_Pa", "atmosphere_Pa",
              "supply_temperature_K", "sample_time_s", "valve_null_V", "valve_min_V", "valve_max_V"),
    "typical": ("moving_mass_kg", "dead_volume_a_m3", "dead_volume_b_m3",
                "valve_sonic_conductance_m3_per_s_Pa", "valve_critical_pressure_ratio",
                "friction_static_N", "friction_coulomb_N", "friction_stribeck_velocity_m_per_s",
                "friction_viscous_N_s_per_m"),
}

#: defaults for the sections a user's rig file may leave out
DEFAULTS = {
    "model": {"friction_smoothing_velocity_m_per_s": 0.001,
              "endstop_stiffness_N_per_m": 1.0e7,
              "endstop_damping_N_s_per_m": 2000.0},
    "sensors": {"position_noise_std_m": 0.0, "position_adc_bits": 16.0,
                "pressure_noise_std_Pa": 0.0, "pressure_quantum_Pa": 0.0},
}

#: physical lower bounds (exclusive) used to refuse impossible values
POSITIVE = ("bore_m", "stroke_m", "supply_Pa", "exhaust_Pa", "atmosphere_Pa", "supply_temperature_K",
            "sample_time_s", "moving_mass_kg", "dead_volume_a_m3", "dead_volume_b_m3",
            "valve_sonic_conductance_m3_per_s_Pa", "friction_stribeck_velocity_m_per_s",
            "friction_smoothing_velocity_m_per_s", "endstop_stiffness_N_per_m")


@dataclasses.dataclass(frozen=True)
class Rig:
    """A rig: a name, a description and a flat mapping of SI parameters.

    Attributes
    ----------
    name:
        Rig id (``paper1-mre``, ``paper2-enfield`` or a user's file stem).
    params:
        Every parameter of every section, ``{name: value}`` in SI units.
    sections:
        ``{section: tuple of parameter names}``, telling known from typical.
    """

    name: str
    description: str
    params: Mapping[str, float]
    sections: Mapping[str, tuple[str, ...]]
    source: str = ""

    def __getitem__(self, key: str) -> float:
        return self.params[key]

    @property
    def stroke_m(self) -> float:
        return float(self.params["stroke_m"])

    @property
    def sample_time_s(self) -> float:
        return float(self.params["sample_time_s"])

    def with_params(self, overrides: Mapping[str, float]) -> "Rig":
        """Return a copy with some parameters replaced; unknown names are refused."""
        unknown = sorted(set(overrides) - set(self.params))
        if unknown:
            raise PneusimError(
                f"rig '{self.name}' has no parameter {unknown[0]!r}; known parameters are: "
                + ", ".join(sorted(self.params)))
        params = dict(self.params)
        params.update({k: float(v) for k, v in overrides.items()})
        _check_values(params, self.source or self.name)
        return dataclasses.replace(self, params=params)


def known_rig_names() -> list[str]:
    """Names of the rigs shipped with pneusim."""
    return sorted(p.stem for p in RIG_DIR.glob("*.toml"))


def load_rig(name_or_path: str | Path) -> Rig:
    """Load a rig by shipped name (``paper2-enfield``) or from a TOML file path.

    Raises
    ------
    InputFileError
        Unknown rig, unreadable file, missing or non-numeric parameter.
    """
    text_name = str(name_or_path)
    path = Path(text_name)
    if not path.suffix and not path.exists():
        path = RIG_DIR / f"{text_name}.toml"
        if not path.exists():
            raise InputFileError(
                f"unknown rig {text_name!r}; expected one of {', '.join(known_rig_names())} "
                "or the path of a rig file (.toml)")
    data = read_toml(path, "rig")
    unknown_sections = sorted(set(data) - set(RIG_SECTIONS) - {"name", "description"})
    if unknown_sections:
        raise InputFileError(f"unknown section; expected one of {', '.join(RIG_SECTIONS)}",
                             path=path, field=unknown_sections[0])
    params: dict[str, float] = {}
    sections: dict[str, tuple[str, ...]] = {}
    for section in RIG_SECTIONS:
        table = dict(DEFAULTS.get(section, {}))
        given = data.get(section, {})
        if not isinstance(given, dict):
            raise InputFileError(f"[{section}] must be a table of NAME = number", path=path, field=section)
        for key, value in given.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InputFileError(f"expected a number, got {value!r}", path=path, field=f"{section}.{key}")
            if key in params:
                raise InputFileError("parameter defined in two sections", path=path, field=f"{section}.{key}")
            table[key] = float(value)
        for key in REQUIRED.get(section, ()):
            if key not in table:
                raise InputFileError("required parameter missing", path=path, field=f"{section}.{key}")
        params.update(table)
        sections[section] = tuple(table)
    _check_values(params, str(path))
    return Rig(name=str(data.get("name", path.stem)), description=str(data.get("description", "")),
               params=params, sections=sections, source=str(path))


def _check_values(params: Mapping[str, float], where: str) -> None:
    for key in POSITIVE:
        if key in params and not params[key] > 0:
            raise InputFileError(f"must be positive, got {params[key]!r}", path=where, field=key)
    if params["rod_m"] < 0 or params["rod_m"] >= params["bore_m"]:
        raise InputFileError("rod diameter must be in [0, bore_m)", path=where, field="rod_m")
    if not 0.0 < params["valve_critical_pressure_ratio"] < 1.0:
        raise InputFileError("must be in (0, 1)", path=where, field="valve_critical_pressure_ratio")
    if params["friction_static_N"] < 0 or params["friction_coulomb_N"] < 0 or params["friction_viscous_N_s_per_m"] < 0:
        raise InputFileError("friction parameters must not be negative", path=where, field="friction_*")


def known_stroke_m(rig_name: str) -> float | None:
    """Stroke of a shipped rig, or ``None`` when the name is not a shipped rig."""
    path = RIG_DIR / f"{rig_name}.toml"
    if not rig_name or not path.exists():
        return None
    return load_rig(path).stroke_m
