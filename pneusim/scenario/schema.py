"""Scenario files: load a TOML scenario, validate it, apply dotted-key overrides.

The schema is documented in ``scenarios/README.md``.  A scenario is kept as a
plain nested ``dict`` (so that a sweep can vary any key by its dotted path, e.g.
``rig.overrides.supply_Pa``) after :func:`validate_scenario` has checked every
key, type and allowed value.  Every mistake raises
:class:`~pneusim.errors.InputFileError` naming the file, the key and what was
expected.
"""

from __future__ import annotations

import copy

from pathlib import Path
from typing import Any

from ..errors import InputFileError
from ..tomlfile import read_toml

__all__ = ["load_scenario", "validate_scenario", "set_dotted", "get_dotted", "SIGNAL_KINDS",
           "IDENTIFIER_KINDS", "OUTPUT_UNITS", "INPUTS", "LAYOUTS"]

SIGNAL_KINDS = ("multisine", "pulses", "steps", "doublets")
IDENTIFIER_KINDS = ("rls", "arx", "armax", "ss", "tf", "published_z", "published_s", "physical_fit")
OUTPUT_UNITS = ("m", "cm", "mm", "sensor_V")
INPUTS = ("valve_cmd_V", "signal")
LAYOUTS = ("generic", "paper1-table1", "paper2-table1")
TIME_UNITS = ("s", "ms", "sample")

_NUM = (int, float)
#: allowed keys per table: name -> (types, required, default)
_TABLES: dict[str, dict[str, tuple]] = {
    "scenario": {"name": (str, True, None), "title": (str, False, ""), "description": (str, False, ""),
                 "layout": (str, False, "generic"), "notes": (list, False, [])},
    "rig": {"name": (str, True, None), "overrides": (dict, False, {}), "effects": (list, False, [])},
    "experiment": {"loop": (str, True, None), "duration_s": (_NUM, True, None), "sample_time_s": (_NUM, False, None),
                   "seed": (int, False, 0), "noise_scale": (_NUM, False, 1.0), "warmup_s": (_NUM, False, 1.0),
                   "initial_position_m": (_NUM, False, None), "signal": (dict, True, None),
                   "controller": (dict, False, {})},
    "data": {"output_unit": (str, False, "m"), "output_offset": (_NUM, False, 0.0),
             "input": (str, False, "valve_cmd_V"), "input_offset": (_NUM, False, 0.0),
             "estimation_fraction": (_NUM, False, 0.5)},
    "metrics": {"report": (list, False, ["fit_percent", "mse"])},
}
_SIGNAL_KEYS = {"kind": str, "unit": str, "offset": _NUM, "components": list, "base": _NUM, "amplitude": list,
                "width_s": list, "rest_s": list, "sign": str, "low": _NUM, "high": _NUM, "hold_s": list,
                "half_s": list, "seed": int, "note": str}
_IDENT_KEYS = {"name": str, "kind": str, "orders": list, "order": int, "forgetting": _NUM,
               "initial_covariance": _NUM, "horizons": list, "nx": int, "np": int, "nz": int,
               "iodelay_s": _NUM, "num": list, "den": list, "delay_samples": int, "input_delay_samples": int,
               "time_units": list, "delay": _NUM, "published": dict, "input_offsets": list, "engine": str, "note": str, "enabled": bool}
METRIC_NAMES = ("fit_percent", "mse", "rmse", "error_std", "wall_time_s")


def load_scenario(path: str | Path) -> dict:
    """Read and validate a scenario file; returns the validated dict (defaults filled in).

    ``rig.name`` may be a shipped rig name or a path relative to the scenario file.
    """
    path = Path(path)
    data = read_toml(path, "scenario")
    rig_name = data.get("rig", {}).get("name") if isinstance(data.get("rig"), dict) else None
    if isinstance(rig_name, str) and rig_name.endswith(".toml") and not Path(rig_name).is_absolute():
        data["rig"]["name"] = str((path.parent / rig_name).resolve())
    return validate_scenario(data, where=str(path))


def _fail(where, key, message):
    raise InputFileError(message, path=where, field=key)


def _check_type(where, key, value, types):
    if isinstance(value, bool) and types is not bool and bool not in (types if isinstance(types, tuple) else (types,)):
        _fail(where, key, f"expected {_type_name(types)}, got {value!r}")
    if not isinstance(value, types):
        _fail(where, key, f"expected {_type_name(types)}, got {value!r}")


def _type_name(types) -> str:
    names = {int: "an integer", float: "a number", str: "a string", list: "a list", dict: "a table",
             bool: "true or false"}
    if types == _NUM:
        return "a number"
    return names.get(types, str(types))


def validate_scenario(data: dict, where: str = "scenario") -> dict:
    """Check every table and key of a scenario dict; return a deep copy with defaults filled in."""
    data = copy.deepcopy(data)
    unknown = sorted(set(data) - set(_TABLES) - {"identifiers", "variants"})
    if unknown:
        _fail(where, unknown[0], f"unknown table; expected one of {', '.join(sorted(_TABLES))}, identifiers, variants")
    for table, keys in _TABLES.items():
        given = data.setdefault(table, {})
        if not isinstance(given, dict):
            _fail(where, table, "expected a table")
        for key in sorted(set(given) - set(keys)):
            _fail(where, f"{table}.{key}", f"unknown key; expected one of {', '.join(keys)}")
        for key, (types, required, default) in keys.items():
            if key not in given:
                if required:
                    _fail(where, f"{table}.{key}", "required key missing")
                given[key] = copy.deepcopy(default)
            elif given[key] is not None:
                _check_type(where, f"{table}.{key}", given[key], types)
    _check_choice(where, "scenario.layout", data["scenario"]["layout"], LAYOUTS)
    _check_choice(where, "experiment.loop", data["experiment"]["loop"], ("open", "closed"))
    _check_choice(where, "data.output_unit", data["data"]["output_unit"], OUTPUT_UNITS)
    _check_choice(where, "data.input", data["data"]["input"], INPUTS)
    for key, value in data["rig"]["overrides"].items():
        _check_type(where, f"rig.overrides.{key}", value, _NUM)
    for i, eff in enumerate(data["rig"]["effects"]):
        _check_type(where, f"rig.effects[{i}]", eff, str)
    exp = data["experiment"]
    if not exp["duration_s"] > 0:
        _fail(where, "experiment.duration_s", f"expected a positive duration in s, got {exp['duration_s']!r}")
    if exp["sample_time_s"] is not None and not exp["sample_time_s"] > 0:
        _fail(where, "experiment.sample_time_s", f"expected a positive sample time in s, got {exp['sample_time_s']!r}")
    if exp["noise_scale"] < 0:
        _fail(where, "experiment.noise_scale", f"expected a number >= 0, got {exp['noise_scale']!r}")
    if exp["loop"] == "closed" and not exp["controller"].get("kp_V_per_m", 0) > 0 and exp["controller"]:
        _fail(where, "experiment.controller.kp_V_per_m", "expected a positive gain in V/m")
    _validate_signal(where, exp["signal"])
    frac = data["data"]["estimation_fraction"]
    if not 0.0 < frac < 1.0:
        _fail(where, "data.estimation_fraction", f"expected a number in (0, 1), got {frac!r}")
    for m in data["metrics"]["report"]:
        _check_choice(where, "metrics.report", m, METRIC_NAMES)
    idents = data.setdefault("identifiers", [])
    if not isinstance(idents, list) or not idents:
        _fail(where, "identifiers", "expected at least one [[identifiers]] table")
    names = set()
    for i, ident in enumerate(idents):
        _validate_identifier(where, f"identifiers[{i}]", ident)
        if ident["name"] in names:
            _fail(where, f"identifiers[{i}].name", f"duplicate identifier name {ident['name']!r}")
        names.add(ident["name"])
    variants = data.setdefault("variants", [])
    for i, var in enumerate(variants):
        if not isinstance(var, dict) or not isinstance(var.get("name"), str):
            _fail(where, f"variants[{i}].name", "expected a table with a string 'name'")
        for key in sorted(set(var) - {"name", "description", "experiment"}):
            _fail(where, f"variants[{i}].{key}", "unknown key; expected name, description, experiment")
        merged = copy.deepcopy(exp)
        merged.update(var.get("experiment", {}))
        if merged["loop"] not in ("open", "closed"):
            _fail(where, f"variants[{i}].experiment.loop", "expected 'open' or 'closed'")
        if "signal" in var.get("experiment", {}):
            _validate_signal(where, merged["signal"], f"variants[{i}].experiment.signal")
    return data


def _check_choice(where, key, value, choices):
    if value not in choices:
        _fail(where, key, f"expected one of {', '.join(map(str, choices))}, got {value!r}")


def _validate_signal(where, sig, prefix="experiment.signal"):
    for key in sorted(set(sig) - set(_SIGNAL_KEYS)):
        _fail(where, f"{prefix}.{key}", f"unknown key; expected one of {', '.join(_SIGNAL_KEYS)}")
    for key, value in sig.items():
        _check_type(where, f"{prefix}.{key}", value, _SIGNAL_KEYS[key])
    if "kind" not in sig:
        _fail(where, f"{prefix}.kind", "required key missing")
    _check_choice(where, f"{prefix}.kind", sig["kind"], SIGNAL_KINDS)
    _check_choice(where, f"{prefix}.unit", sig.setdefault("unit", "native"), ("native", "m", "sensor_V"))
    if sig["kind"] == "multisine":
        comps = sig.get("components")
        if not comps or not all(isinstance(c, list) and len(c) in (2, 3) and all(isinstance(x, _NUM) for x in c)
                                for c in comps):
            _fail(where, f"{prefix}.components", "expected a list of [amplitude, frequency_Hz(, phase_rad)]")
    for key in ("amplitude", "width_s", "rest_s", "hold_s", "half_s"):
        if key in sig and (len(sig[key]) != 2 or not all(isinstance(x, _NUM) for x in sig[key])):
            _fail(where, f"{prefix}.{key}", "expected [low, high]")
    if "sign" in sig:
        _check_choice(where, f"{prefix}.sign", sig["sign"], ("both", "positive", "negative"))


def _validate_identifier(where, prefix, ident):
    if not isinstance(ident, dict):
        _fail(where, prefix, "expected a table")
    for key in sorted(set(ident) - set(_IDENT_KEYS)):
        _fail(where, f"{prefix}.{key}", f"unknown key; expected one of {', '.join(_IDENT_KEYS)}")
    for key, value in ident.items():
        _check_type(where, f"{prefix}.{key}", value, _IDENT_KEYS[key])
    for key in ("name", "kind"):
        if key not in ident:
            _fail(where, f"{prefix}.{key}", "required key missing")
    kind = ident["kind"]
    _check_choice(where, f"{prefix}.kind", kind, IDENTIFIER_KINDS)
    need = {"rls": ("order",), "arx": ("orders",), "armax": ("orders",), "ss": ("nx",), "tf": ("np", "nz"),
            "published_z": ("num", "den"), "published_s": ("num", "den")}.get(kind, ())
    for key in need:
        if key not in ident:
            _fail(where, f"{prefix}.{key}", f"required for kind = {kind!r}")
    n_orders = {"arx": 3, "armax": 4}.get(kind)
    if n_orders and (len(ident["orders"]) != n_orders or not all(isinstance(o, int) and o >= 0 for o in ident["orders"])):
        _fail(where, f"{prefix}.orders", f"expected {n_orders} non-negative integers for {kind}")
    if kind == "rls":
        if ident["order"] < 1:
            _fail(where, f"{prefix}.order", "expected a positive integer")
        lam = ident.setdefault("forgetting", 0.99)
        if not 0.0 < lam <= 1.0:
            _fail(where, f"{prefix}.forgetting", f"expected a number in (0, 1], got {lam!r}")
        if not ident.setdefault("initial_covariance", 1000.0) > 0:
            _fail(where, f"{prefix}.initial_covariance", "expected a positive number")
        _check_choice(where, f"{prefix}.engine", ident.setdefault("engine", "auto"), ("auto", "sysid", "pneusim"))
        hs = ident.setdefault("horizons", [1])
        if not hs or not all(isinstance(h, int) and h >= 1 for h in hs):
            _fail(where, f"{prefix}.horizons", "expected a list of positive integers (prediction steps)")
    if kind == "published_s":
        units = ident.setdefault("time_units", ["s"])
        for u in units:
            _check_choice(where, f"{prefix}.time_units", u, TIME_UNITS)
    ident.setdefault("enabled", True)


def get_dotted(data: dict, key: str) -> Any:
    """Value at a dotted path (``identifiers.0.order`` indexes lists)."""
    node = data
    for part in key.split("."):
        node = node[int(part)] if isinstance(node, list) else node[part]
    return node


def set_dotted(data: dict, key: str, value: Any, where: str = "sweep") -> None:
    """Set the value at a dotted path in place; list items by index, missing tables created.

    Unknown top-level tables are refused here; unknown keys deeper down are
    caught by :func:`validate_scenario` afterwards.
    """
    parts = key.split(".")
    if parts[0] not in set(_TABLES) | {"identifiers", "variants"}:
        raise InputFileError(f"cannot vary {key!r}: unknown scenario table {parts[0]!r}", path=where, field=key)
    node = data
    for part in parts[:-1]:
        if isinstance(node, list):
            try:
                node = node[int(part)]
            except (ValueError, IndexError):
                raise InputFileError(f"cannot vary {key!r}: no list item {part!r}", path=where, field=key) from None
        else:
            node = node.setdefault(part, {})
    last = parts[-1]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
