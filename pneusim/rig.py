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
import difflib
import json
import math
from pathlib import Path
from typing import Mapping

from .errors import InputFileError, PneusimError
from .outputs import write_text_atomic
from .tomlfile import read_toml

__all__ = ["Rig", "load_rig", "known_rig_names", "rig_variant_names", "known_stroke_m", "RIG_SECTIONS",
           "RANGES", "range_text", "allowed_parameters", "write_rig"]

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

#: parameters a rig file may give besides the required ones and the defaults, by section
OPTIONAL = {"known": ("position_sensor_V_per_m",)}

_INF = math.inf

#: physical range of every parameter: ``name: (low, high, low_included, high_included, unit)``;
#: pairs (supply above exhaust, null between the valve's limits, rod thinner than the bore) are
#: checked by :func:`_check_values`
RANGES = {
    "bore_m": (0.0, _INF, False, False, "m"),
    "rod_m": (0.0, _INF, True, False, "m"),
    "stroke_m": (0.0, _INF, False, False, "m"),
    "supply_Pa": (0.0, _INF, False, False, "Pa absolute"),
    "exhaust_Pa": (0.0, _INF, False, False, "Pa absolute"),
    "atmosphere_Pa": (0.0, _INF, False, False, "Pa absolute"),
    "supply_temperature_K": (0.0, _INF, False, False, "K"),
    "sample_time_s": (0.0, _INF, False, False, "s"),
    "valve_null_V": (-_INF, _INF, False, False, "V"),
    "valve_min_V": (-_INF, _INF, False, False, "V"),
    "valve_max_V": (-_INF, _INF, False, False, "V"),
    "position_sensor_V_per_m": (0.0, _INF, False, False, "V/m"),
    "moving_mass_kg": (0.0, _INF, False, False, "kg"),
    "dead_volume_a_m3": (0.0, _INF, False, False, "m3"),
    "dead_volume_b_m3": (0.0, _INF, False, False, "m3"),
    "valve_sonic_conductance_m3_per_s_Pa": (0.0, _INF, False, False, "m3/(s Pa)"),
    "valve_critical_pressure_ratio": (0.0, 1.0, False, False, ""),
    "friction_static_N": (0.0, _INF, True, False, "N"),
    "friction_coulomb_N": (0.0, _INF, True, False, "N"),
    "friction_stribeck_velocity_m_per_s": (0.0, _INF, False, False, "m/s"),
    "friction_viscous_N_s_per_m": (0.0, _INF, True, False, "N s/m"),
    "friction_smoothing_velocity_m_per_s": (0.0, _INF, False, False, "m/s"),
    "endstop_stiffness_N_per_m": (0.0, _INF, False, False, "N/m"),
    "endstop_damping_N_s_per_m": (0.0, _INF, True, False, "N s/m"),
    "position_noise_std_m": (0.0, _INF, True, False, "m"),
    "position_adc_bits": (0.0, 32.0, True, True, "bits"),
    "pressure_noise_std_Pa": (0.0, _INF, True, False, "Pa"),
    "pressure_quantum_Pa": (0.0, _INF, True, False, "Pa"),
}
#: parameters that must be whole numbers
INTEGER = ("position_adc_bits",)


def allowed_parameters() -> dict[str, tuple[str, ...]]:
    """``{section: parameter names}`` a rig file may hold (required, optional and defaulted)."""
    return {section: tuple(dict.fromkeys(REQUIRED.get(section, ()) + OPTIONAL.get(section, ())
                                         + tuple(DEFAULTS.get(section, {}))))
            for section in RIG_SECTIONS}


def range_text(name: str) -> str:
    """The allowed range of a rig parameter in words, e.g. ``'> 0 kg'`` or ``'in (0, 1)'``."""
    lo, hi, lo_in, hi_in, unit = RANGES[name]
    unit = f" {unit}" if unit else ""
    if hi == _INF and lo == -_INF:
        return f"a finite number{unit}"
    if hi == _INF:
        return f"{'>=' if lo_in else '>'} {lo:g}{unit}"
    return f"in {'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}{unit}"


def suggest(name: str, candidates) -> str:
    """``"; did you mean 'x'?"`` for a misspelt name, or an empty string."""
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


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
    #: parameters changed by :meth:`with_params` since the rig was loaded, ``{name: value}``
    #: (written into recordings so that a run can be repeated)
    overrides: Mapping[str, float] = dataclasses.field(default_factory=dict)
    #: optional effects of a rig variant's ``[effects.NAME]`` tables, in ``NAME:PARAM=VALUE,...`` form;
    #: data only: :func:`pneusim.simulate.rig_effects` builds (and checks) them, a scenario adds them to
    #: its effect list, :func:`pneusim.simulate.simulate` does not
    effects: tuple[str, ...] = ()
    #: the data-sheet rig a variant file describes more realistically ("" for a data-sheet rig)
    variant_of: str = ""
    #: the ``[daq]`` table as read (channels, ranges, volts per metre), or ``None``; data only: the
    #: mixed-reality environment's ``nidaqmx`` plant checks it (:func:`pneusim.mre.daq.daq_config`)
    daq: Mapping | None = None

    def __getitem__(self, key: str) -> float:
        return self.params[key]

    @property
    def stroke_m(self) -> float:
        return float(self.params["stroke_m"])

    @property
    def sample_time_s(self) -> float:
        return float(self.params["sample_time_s"])

    def with_params(self, overrides: Mapping[str, float], origin: str | None = None) -> "Rig":
        """Return a copy with some parameters replaced; unknown names and values out of range are refused.

        ``origin`` names where the overrides come from (e.g. ``"--param"``) so that a bad value is
        blamed on it rather than on the rig file.
        """
        unknown = sorted(set(overrides) - set(self.params))
        if unknown:
            where = f"{origin} {unknown[0]}: " if origin else ""
            hint = suggest(unknown[0], self.params) or ("; known parameters are: " + ", ".join(sorted(self.params)))
            raise PneusimError(f"{where}rig '{self.name}' has no parameter {unknown[0]!r}{hint}")
        params = dict(self.params)
        for key, value in overrides.items():
            try:
                params[key] = float(value)
            except (TypeError, ValueError):
                raise PneusimError(f"{origin + ' ' if origin else ''}{key}: expected a number, got {value!r}") from None
        _check_values(params, self.source or self.name, overridden=overrides, origin=origin or "override")
        changed = {**self.overrides, **{k: params[k] for k in overrides}}
        return dataclasses.replace(self, params=params, overrides=changed)

    @property
    def is_shipped(self) -> bool:
        """True for a rig that ships with pneusim (``load_rig(name)`` finds it by name)."""
        return bool(self.source) and Path(self.source).resolve() == (RIG_DIR / f"{self.name}.toml").resolve()

    def to_toml(self, effects=()) -> str:
        """This rig as a rig file (the text :func:`load_rig` reads back to the same parameters).

        ``effects`` (:class:`~pneusim.model.Effect` objects, e.g. a fit's ``effects_``) are written as
        ``[effects.NAME]`` tables, after those the rig already carries.
        """
        lines = [f"# Rig file for pneusim ({self.name}); every name carries its SI unit.",
                 f"name = {_toml_string(self.name)}",
                 f"description = {_toml_string(self.description)}"]
        for section in RIG_SECTIONS:
            lines += ["", f"[{section}]"]
            lines += [f"{key} = {float(self.params[key])!r}" for key in self.sections.get(section, ())]
        texts = list(getattr(self, "effects", ()) or ()) + [e.to_text() for e in effects]
        for text in texts:
            name, _, rest = text.partition(":")
            lines += ["", f"[effects.{name}]"]
            for item in filter(None, rest.split(",")):
                key, _, value = item.partition("=")
                try:
                    lines.append(f"{key} = {float(value)!r}")
                except ValueError:
                    lines.append(f"{key} = {_toml_string(value)}")
        if self.daq is not None:                      # the NI card's channels (pneusim mre --plant nidaqmx)
            lines += ["", "[daq]"] + [f"{key} = {_toml_value(value)}" for key, value in self.daq.items()]
        return "\n".join(lines) + "\n"


def _toml_string(text: str) -> str:
    return json.dumps(str(text))   # a JSON string is a valid TOML basic string


def _toml_value(value) -> str:
    """A value read from TOML written back as TOML (the same type and value when read again)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_string(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
    return repr(value)


def write_rig(rig: Rig, path: str | Path, effects=()) -> Path:
    """Write ``rig`` (and ``effects``, as ``[effects.NAME]`` tables) as a rig file (``.toml``) that
    ``load_rig`` and ``--rig PATH`` accept (written atomically: the file is whole or not replaced)."""
    return write_text_atomic(path, rig.to_toml(effects))


def known_rig_names() -> list[str]:
    """Names of the data-sheet rigs shipped with pneusim (the rigs of ``shared/spec/rigs.toml``)."""
    return sorted(p.stem for p in RIG_DIR.glob("*.toml") if not _is_variant(p))


def rig_variant_names() -> list[str]:
    """Names of the shipped rig variants (files with ``variant_of``, e.g. ``paper2-enfield-realistic``)."""
    return sorted(p.stem for p in RIG_DIR.glob("*.toml") if _is_variant(p))


def _is_variant(path: Path) -> bool:
    try:
        return "variant_of" in read_toml(path, "rig")
    except InputFileError:
        return False


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
                f"unknown rig {text_name!r}; expected one of {', '.join(known_rig_names() + rig_variant_names())} "
                "or the path of a rig file (.toml)")
    data = read_toml(path, "rig")
    unknown_sections = sorted(set(data) - set(RIG_SECTIONS) - {"name", "description", "variant_of", "effects", "daq"})
    if unknown_sections:
        raise InputFileError(f"unknown section; expected one of {', '.join(RIG_SECTIONS + ('effects', 'daq'))}",
                             path=path, field=unknown_sections[0])
    params: dict[str, float] = {}
    sections: dict[str, tuple[str, ...]] = {}
    for section in RIG_SECTIONS:
        table = dict(DEFAULTS.get(section, {}))
        given = data.get(section, {})
        if not isinstance(given, dict):
            raise InputFileError(f"[{section}] must be a table of NAME = number", path=path, field=section)
        allowed = allowed_parameters()[section]
        for key, value in given.items():
            if key not in allowed:
                others = [k for sec in RIG_SECTIONS for k in allowed_parameters()[sec]]
                raise InputFileError(f"unknown parameter{suggest(key, others)} (a [{section}] parameter is one "
                                     f"of: {', '.join(allowed)})", path=path, field=f"{section}.{key}")
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
               params=params, sections=sections, source=str(path), effects=_effects_section(data, path),
               variant_of=str(data.get("variant_of", "")), daq=_daq_table(data, path))


def _daq_table(data: dict, path: Path) -> dict | None:
    """The ``[daq]`` table as read, or ``None`` when absent (its keys are checked where the card is used)."""
    if "daq" not in data:
        return None
    if not isinstance(data["daq"], dict):
        raise InputFileError("[daq] must be a table of channel names and numbers", path=path, field="daq")
    return data["daq"]


def _effects_section(data: dict, path: Path) -> tuple[str, ...]:
    """``[effects.NAME]`` tables (``PARAM = value``, options as strings) -> ``("NAME:PARAM=VALUE,...", ...)``.

    Only their form is checked here; :func:`pneusim.simulate.rig_effects` builds each effect and names
    this file and ``effects.NAME`` for an unknown effect or a bad value.
    """
    table = data.get("effects", {})
    if not isinstance(table, dict):
        raise InputFileError("[effects] must hold [effects.NAME] tables", path=path, field="effects")
    texts = []
    for name, values in table.items():
        if not isinstance(values, dict):
            raise InputFileError("expected a table [effects.NAME] of PARAM = value", path=path,
                                 field=f"effects.{name}")
        texts.append(name + (":" + ",".join(f"{k}={v}" for k, v in values.items()) if values else ""))
    return tuple(texts)


def _check_values(params: Mapping[str, float], where: str, overridden: Mapping[str, float] = (),
                  origin: str = "override") -> None:
    """Refuse a value outside its physical range, naming the parameter and the range.

    A fault that involves an overridden parameter is blamed on ``origin`` (``--param``, a scenario's
    ``rig.overrides``); any other on the rig file ``where``.
    """
    def fail(keys: tuple[str, ...], message: str):
        blamed = [k for k in keys if k in overridden]
        if blamed:
            err = InputFileError(f"{origin} {blamed[0]}={params[blamed[0]]!r}: {message}")
            err.field, err.reason = blamed[0], message   # a scenario names its own key from these
            raise err
        raise InputFileError(message, path=where, field=keys[0])

    for key, value in params.items():
        if key not in RANGES:
            continue
        lo, hi, lo_in, hi_in, _unit = RANGES[key]
        ok = math.isfinite(value) and (value >= lo if lo_in else value > lo) and (value <= hi if hi_in else value < hi)
        if ok and key in INTEGER and value != int(value):
            ok = False
        if not ok:
            if lo == 0.0 and not lo_in and hi == _INF:
                fail((key,), f"must be positive ({range_text(key)}), got {value!r}")
            if key in INTEGER:
                fail((key,), f"must be a whole number {range_text(key)} (0: no converter steps), got {value!r}")
            fail((key,), f"must be {range_text(key)}, got {value!r}")
    if params["rod_m"] >= params["bore_m"]:
        fail(("rod_m", "bore_m"), f"rod_m must be smaller than bore_m ({params['bore_m']!r} m), "
                                  f"got {params['rod_m']!r} m")
    if not params["supply_Pa"] > params["exhaust_Pa"]:
        fail(("supply_Pa", "exhaust_Pa"), f"supply_Pa must be above exhaust_Pa ({params['exhaust_Pa']!r} Pa), "
                                          f"got {params['supply_Pa']!r} Pa")
    if not params["valve_min_V"] < params["valve_null_V"] < params["valve_max_V"]:
        fail(("valve_null_V", "valve_min_V", "valve_max_V"),
             f"valve_null_V must lie strictly between valve_min_V and valve_max_V, got "
             f"{params['valve_min_V']!r} < {params['valve_null_V']!r} < {params['valve_max_V']!r} V")


def known_stroke_m(rig_name: str) -> float | None:
    """Stroke of a shipped rig, or ``None`` when the name is not a shipped rig."""
    path = RIG_DIR / f"{rig_name}.toml"
    if not rig_name or not path.exists():
        return None
    return load_rig(path).stroke_m
