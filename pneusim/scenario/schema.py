"""Scenario files: load a TOML scenario, validate it, apply dotted-key overrides.

The schema is documented in ``scenarios/README.md``.  A scenario is kept as a
plain nested ``dict`` (so that a sweep can vary any key by its dotted path, e.g.
``rig.overrides.supply_Pa``) after :func:`validate_scenario` has checked every
key, type and allowed value, and the parts that need the rig: the rig name, its
parameter overrides, the effects, the number of samples and the signal's unit.
Every mistake raises :class:`~pneusim.errors.InputFileError` naming the file,
the key and what was expected.
"""

from __future__ import annotations

import copy

from pathlib import Path
from typing import Any

from ..errors import InputFileError, PneusimError
from ..experiment import MAX_SAMPLES
from ..tomlfile import read_toml

__all__ = ["load_scenario", "validate_scenario", "set_dotted", "get_dotted", "SIGNAL_KINDS",
           "IDENTIFIER_KINDS", "OUTPUT_UNITS", "INPUTS", "LAYOUTS", "MIN_SAMPLES"]

SIGNAL_KINDS = ("multisine", "pulses", "steps", "doublets")
IDENTIFIER_KINDS = ("rls", "arx", "armax", "ss", "tf", "published_z", "published_s", "physical_fit")
OUTPUT_UNITS = ("m", "cm", "mm", "sensor_V")
INPUTS = ("valve_cmd_V", "signal")
LAYOUTS = ("generic", "paper1-table1", "paper2-table1")
TIME_UNITS = ("s", "ms", "sample")
METRIC_NAMES = ("fit_percent", "mse", "rmse", "error_std", "wall_time_s")
#: fewest samples an experiment may have
MIN_SAMPLES = 50

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
_CONTROLLER_KEYS = {"kind": str, "kp_V_per_m": _NUM, "u0_V": _NUM, "u_min_V": _NUM, "u_max_V": _NUM}
_SIGNAL_KEYS = {"kind": str, "unit": str, "offset": _NUM, "components": list, "base": _NUM, "amplitude": list,
                "width_s": list, "rest_s": list, "sign": str, "low": _NUM, "high": _NUM, "hold_s": list,
                "half_s": list, "seed": int, "note": str}
_SIGNAL_COMMON = ("kind", "unit", "offset", "seed", "note")
_SIGNAL_KIND_KEYS = {"multisine": ("components",), "pulses": ("base", "amplitude", "width_s", "rest_s", "sign"),
                     "steps": ("low", "high", "hold_s"), "doublets": ("amplitude", "half_s", "rest_s")}
_IDENT_KEYS = {"name": str, "kind": str, "orders": list, "order": int, "forgetting": _NUM,
               "initial_covariance": _NUM, "horizons": list, "nx": int, "np": int, "nz": int,
               "iodelay_s": _NUM, "num": list, "den": list, "time_units": list, "delay": _NUM, "published": dict,
               "input_offsets": list, "engine": str, "note": str, "enabled": bool, "model_effects": str,
               "fit_starts": int}
_IDENT_COMMON = ("name", "kind", "published", "enabled", "note")
_IDENT_KIND_KEYS = {"rls": ("order", "forgetting", "initial_covariance", "horizons", "engine"),
                    "arx": ("orders",), "armax": ("orders",), "ss": ("nx",), "tf": ("np", "nz", "iodelay_s"),
                    "published_z": ("num", "den", "input_offsets"),
                    "published_s": ("num", "den", "delay", "time_units"), "physical_fit": ("model_effects", "fit_starts")}
#: ``[[rig_variants]]``: the scenario re-run on another rig (e.g. a realistic variant), reported side by side
_RIG_VARIANT_KEYS = {"name": (str, True, None), "rig": (str, True, None), "effects": (list, False, []),
                     "description": (str, False, ""), "physical": (bool, False, False)}
#: ``[[conditions]]``: operating conditions the models trained on the main run are validated on
_CONDITION_KEYS = {"name": (str, True, None), "description": (str, False, ""), "rig_overrides": (dict, False, {}),
                   "experiment": (dict, False, {})}


def load_scenario(path: str | Path) -> dict:
    """Read and validate a scenario file; returns the validated dict (defaults filled in).

    ``rig.name`` may be a shipped rig name or a path relative to the scenario file.
    """
    path = Path(path)
    data = read_toml(path, "scenario")
    rig_name = data.get("rig", {}).get("name") if isinstance(data.get("rig"), dict) else None
    if isinstance(rig_name, str) and rig_name.endswith(".toml") and not Path(rig_name).is_absolute():
        data["rig"]["name"] = str((path.parent / rig_name).resolve())
    for var in data.get("rig_variants", []) if isinstance(data.get("rig_variants"), list) else []:
        name = var.get("rig") if isinstance(var, dict) else None
        if isinstance(name, str) and name.endswith(".toml") and not Path(name).is_absolute():
            var["rig"] = str((path.parent / name).resolve())
    return validate_scenario(data, where=str(path))


def _fail(where, key, message):
    raise InputFileError(message, path=where, field=key)


def _check_type(where, key, value, types):
    allowed = types if isinstance(types, tuple) else (types,)
    if (isinstance(value, bool) and bool not in allowed) or not isinstance(value, allowed):
        _fail(where, key, f"expected {_type_name(types)}, got {value!r}")


def _type_name(types) -> str:
    names = {int: "an integer", float: "a number", str: "a string", list: "a list", dict: "a table",
             bool: "true or false"}
    if types == _NUM:
        return "a number"
    return names.get(types, str(types))


def _numbers(where, key, value, n=None, what="numbers"):
    """``value`` must be a list of numbers (of length ``n`` if given)."""
    ok = isinstance(value, list) and all(isinstance(x, _NUM) and not isinstance(x, bool) for x in value)
    if not ok or (n is not None and len(value) != n) or not value:
        size = f"{n} " if n is not None else ""
        _fail(where, key, f"expected a non-empty list of {size}{what}, got {value!r}")


def _check_keys(where, prefix, given, allowed, context=""):
    for key in sorted(set(given) - set(allowed)):
        _fail(where, f"{prefix}.{key}", f"unknown key{context}; expected one of {', '.join(allowed)}")


def validate_scenario(data: dict, where: str = "scenario") -> dict:
    """Check every table and key of a scenario dict; return a deep copy with defaults filled in."""
    data = copy.deepcopy(data)
    unknown = sorted(set(data) - set(_TABLES) - {"identifiers", "variants", "rig_variants", "conditions"})
    if unknown:
        _fail(where, unknown[0], f"unknown table; expected one of {', '.join(sorted(_TABLES))}, identifiers, "
                                 "variants, rig_variants, conditions")
    for table, keys in _TABLES.items():
        given = data.setdefault(table, {})
        if not isinstance(given, dict):
            _fail(where, table, "expected a table")
        _check_keys(where, table, given, keys)
        for key, (types, required, default) in keys.items():
            if key not in given:
                if required:
                    _fail(where, f"{table}.{key}", "required key missing")
                given[key] = copy.deepcopy(default)
            elif given[key] is not None:
                _check_type(where, f"{table}.{key}", given[key], types)
    for i, note in enumerate(data["scenario"]["notes"]):
        _check_type(where, f"scenario.notes[{i}]", note, str)
    _check_choice(where, "scenario.layout", data["scenario"]["layout"], LAYOUTS)
    _check_choice(where, "data.output_unit", data["data"]["output_unit"], OUTPUT_UNITS)
    _check_choice(where, "data.input", data["data"]["input"], INPUTS)
    for key, value in data["rig"]["overrides"].items():
        _check_type(where, f"rig.overrides.{key}", value, _NUM)
    for i, eff in enumerate(data["rig"]["effects"]):
        _check_type(where, f"rig.effects[{i}]", eff, str)
    exp = data["experiment"]
    _validate_experiment(where, exp, "experiment")
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
    if not isinstance(variants, list):
        _fail(where, "variants", "expected [[variants]] tables")
    merged_exps = []
    for i, var in enumerate(variants):
        if not isinstance(var, dict) or not isinstance(var.get("name"), str):
            _fail(where, f"variants[{i}].name", "expected a table with a string 'name'")
        _check_keys(where, f"variants[{i}]", var, ("name", "description", "experiment"))
        vexp = var.get("experiment", {})
        if not isinstance(vexp, dict):
            _fail(where, f"variants[{i}].experiment", "expected a table of [experiment] keys")
        prefix = f"variants[{i}].experiment"
        _check_keys(where, prefix, vexp, _TABLES["experiment"])
        for key, value in vexp.items():
            if value is not None:
                _check_type(where, f"{prefix}.{key}", value, _TABLES["experiment"][key][0])
        merged = copy.deepcopy(exp)
        merged.update(copy.deepcopy(vexp))
        _validate_experiment(where, merged, prefix)
        merged_exps.append((prefix, merged))
    _validate_with_rig(where, data, merged_exps)
    _validate_rig_variants(where, data)
    _validate_conditions(where, data)
    return data


def _list_of_tables(where, data, key, keys):
    """``[[key]]`` tables with the given ``{name: (types, required, default)}``; defaults filled in."""
    items = data.setdefault(key, [])
    if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
        _fail(where, key, f"expected [[{key}]] tables")
    names = set()
    for i, item in enumerate(items):
        _check_keys(where, f"{key}[{i}]", item, keys)
        for k, (types, required, default) in keys.items():
            if k not in item:
                if required:
                    _fail(where, f"{key}[{i}].{k}", "required key missing")
                item[k] = copy.deepcopy(default)
            else:
                _check_type(where, f"{key}[{i}].{k}", item[k], types)
        if item["name"] in names:
            _fail(where, f"{key}[{i}].name", f"duplicate name {item['name']!r}")
        names.add(item["name"])
    return items


def _validate_rig_variants(where, data):
    """``[[rig_variants]]``: the rig loads (shipped name or file), the effects parse."""
    from ..model import parse_effect_text
    from ..rig import load_rig

    for i, var in enumerate(_list_of_tables(where, data, "rig_variants", _RIG_VARIANT_KEYS)):
        try:
            load_rig(var["rig"])
        except PneusimError as exc:
            _fail(where, f"rig_variants[{i}].rig", str(exc))
        for j, text in enumerate(var["effects"]):
            _check_type(where, f"rig_variants[{i}].effects[{j}]", text, str)
            try:
                parse_effect_text(text)
            except (PneusimError, TypeError, ValueError) as exc:
                _fail(where, f"rig_variants[{i}].effects[{j}]", f"{exc} (form: 'NAME:PARAM=VALUE,...')")


def _validate_conditions(where, data):
    """``[[conditions]]``: rig overrides the rig has (with possible values) and a valid merged experiment."""
    from ..rig import load_rig

    conds = _list_of_tables(where, data, "conditions", _CONDITION_KEYS)
    if not conds:
        return
    rig = load_rig(data["rig"]["name"]).with_params(data["rig"]["overrides"])
    for i, cond in enumerate(conds):
        prefix = f"conditions[{i}]"
        for key, value in cond["rig_overrides"].items():
            _check_type(where, f"{prefix}.rig_overrides.{key}", value, _NUM)
            if key not in rig.params:
                _fail(where, f"{prefix}.rig_overrides.{key}", f"unknown parameter of rig {rig.name!r}")
        try:
            rig.with_params(cond["rig_overrides"])
        except PneusimError as exc:
            _fail(where, f"{prefix}.rig_overrides", getattr(exc, "reason", str(exc)))
        cexp = cond["experiment"]
        _check_keys(where, f"{prefix}.experiment", cexp, _TABLES["experiment"])
        for key, value in cexp.items():
            _check_type(where, f"{prefix}.experiment.{key}", value, _TABLES["experiment"][key][0])
        merged = copy.deepcopy(data["experiment"])
        merged.update(copy.deepcopy(cexp))
        _validate_experiment(where, merged, f"{prefix}.experiment")


def _check_choice(where, key, value, choices):
    if value not in choices:
        _fail(where, key, f"expected one of {', '.join(map(str, choices))}, got {value!r}")


def _validate_experiment(where, exp, prefix):
    """The [experiment] table (or a variant's merged copy): values, controller and signal."""
    _check_choice(where, f"{prefix}.loop", exp["loop"], ("open", "closed"))
    if not 0 < exp["duration_s"] < float("inf"):
        _fail(where, f"{prefix}.duration_s", f"expected a positive finite duration in s, got {exp['duration_s']!r}")
    if exp.get("sample_time_s") is not None and not 0 < exp["sample_time_s"] < float("inf"):
        _fail(where, f"{prefix}.sample_time_s", f"expected a positive sample time in s, got {exp['sample_time_s']!r}")
    for key in ("noise_scale", "warmup_s", "seed"):
        if exp.get(key) is not None and not (exp[key] >= 0 and exp[key] < float("inf")):   # NaN fails too
            _fail(where, f"{prefix}.{key}", f"expected a finite number >= 0, got {exp[key]!r}")
    ctrl = exp.get("controller") or {}
    _check_keys(where, f"{prefix}.controller", ctrl, _CONTROLLER_KEYS)
    for key, value in ctrl.items():
        _check_type(where, f"{prefix}.controller.{key}", value, _CONTROLLER_KEYS[key])
    if "kind" in ctrl:
        _check_choice(where, f"{prefix}.controller.kind", ctrl["kind"], ("proportional",))
    if "kp_V_per_m" in ctrl and not ctrl["kp_V_per_m"] > 0:
        _fail(where, f"{prefix}.controller.kp_V_per_m", f"expected a positive gain in V/m, got {ctrl['kp_V_per_m']!r}")
    _validate_signal(where, exp["signal"], f"{prefix}.signal")


def _validate_signal(where, sig, prefix="experiment.signal"):
    _check_keys(where, prefix, sig, _SIGNAL_KEYS)
    for key, value in sig.items():
        _check_type(where, f"{prefix}.{key}", value, _SIGNAL_KEYS[key])
    if "kind" not in sig:
        _fail(where, f"{prefix}.kind", "required key missing")
    _check_choice(where, f"{prefix}.kind", sig["kind"], SIGNAL_KINDS)
    _check_keys(where, prefix, sig, _SIGNAL_COMMON + _SIGNAL_KIND_KEYS[sig["kind"]],
                context=f" for kind = {sig['kind']!r}")
    _check_choice(where, f"{prefix}.unit", sig.setdefault("unit", "native"), ("native", "m", "sensor_V"))
    if sig["kind"] == "multisine":
        comps = sig.get("components")
        if not comps or not all(isinstance(c, list) and len(c) in (2, 3) and all(isinstance(x, _NUM) for x in c)
                                and c[1] >= 0 for c in comps):
            _fail(where, f"{prefix}.components", "expected a list of [amplitude, frequency_Hz >= 0(, phase_rad)]")
    for key in ("amplitude", "width_s", "rest_s", "hold_s", "half_s"):
        if key in sig:
            _numbers(where, f"{prefix}.{key}", sig[key], 2, "numbers [low, high]")
            if sig[key][0] > sig[key][1]:
                _fail(where, f"{prefix}.{key}", f"expected [low, high] with low <= high, got {sig[key]!r}")
            if key.endswith("_s") and not sig[key][0] > 0:
                _fail(where, f"{prefix}.{key}", f"expected positive durations in s, got {sig[key]!r}")
    if "sign" in sig:
        _check_choice(where, f"{prefix}.sign", sig["sign"], ("both", "positive", "negative"))
    if sig.get("seed", 0) < 0:
        _fail(where, f"{prefix}.seed", f"expected an integer >= 0, got {sig['seed']!r}")


def _validate_identifier(where, prefix, ident):
    if not isinstance(ident, dict):
        _fail(where, prefix, "expected a table")
    _check_keys(where, prefix, ident, _IDENT_KEYS)
    for key, value in ident.items():
        _check_type(where, f"{prefix}.{key}", value, _IDENT_KEYS[key])
    for key in ("name", "kind"):
        if key not in ident:
            _fail(where, f"{prefix}.{key}", "required key missing")
    kind = ident["kind"]
    _check_choice(where, f"{prefix}.kind", kind, IDENTIFIER_KINDS)
    _check_keys(where, prefix, ident, _IDENT_COMMON + _IDENT_KIND_KEYS[kind], context=f" for kind = {kind!r}")
    need = {"rls": ("order",), "arx": ("orders",), "armax": ("orders",), "ss": ("nx",), "tf": ("np", "nz"),
            "published_z": ("num", "den"), "published_s": ("num", "den")}.get(kind, ())
    for key in need:
        if key not in ident:
            _fail(where, f"{prefix}.{key}", f"required for kind = {kind!r}")
    for key, value in ident.get("published", {}).items():
        _check_type(where, f"{prefix}.published.{key}", value, _NUM)
    n_orders = {"arx": 3, "armax": 4}.get(kind)
    if n_orders and (len(ident["orders"]) != n_orders
                     or not all(isinstance(o, int) and not isinstance(o, bool) and o >= 0 for o in ident["orders"])):
        _fail(where, f"{prefix}.orders", f"expected {n_orders} non-negative integers for {kind}, got {ident['orders']!r}")
    if kind == "rls":
        if ident["order"] < 1:
            _fail(where, f"{prefix}.order", f"expected a positive integer, got {ident['order']!r}")
        lam = ident.setdefault("forgetting", 0.99)
        if not 0.0 < lam <= 1.0:
            _fail(where, f"{prefix}.forgetting", f"expected a number in (0, 1], got {lam!r}")
        if not ident.setdefault("initial_covariance", 1000.0) > 0:
            _fail(where, f"{prefix}.initial_covariance", "expected a positive number")
        _check_choice(where, f"{prefix}.engine", ident.setdefault("engine", "auto"), ("auto", "sysid", "pneusim"))
        hs = ident.setdefault("horizons", [1])
        if not hs or not all(isinstance(h, int) and not isinstance(h, bool) and h >= 1 for h in hs):
            _fail(where, f"{prefix}.horizons", f"expected a list of positive integers (prediction steps), got {hs!r}")
    if kind == "ss" and ident["nx"] < 1:
        _fail(where, f"{prefix}.nx", f"expected a positive integer, got {ident['nx']!r}")
    if kind == "tf":
        if ident["np"] < 1:
            _fail(where, f"{prefix}.np", f"expected a positive integer, got {ident['np']!r}")
        if not 0 <= ident["nz"] <= ident["np"]:
            _fail(where, f"{prefix}.nz", f"expected an integer in [0, np = {ident['np']}], got {ident['nz']!r}")
        if ident.get("iodelay_s", 0.0) < 0:
            _fail(where, f"{prefix}.iodelay_s", f"expected a delay >= 0 in s, got {ident['iodelay_s']!r}")
    if kind in ("published_z", "published_s"):
        _numbers(where, f"{prefix}.num", ident["num"])
        _numbers(where, f"{prefix}.den", ident["den"])
        if ident["den"][0] == 0:
            _fail(where, f"{prefix}.den", "expected a non-zero leading coefficient (descending powers)")
        if len(ident["num"]) > len(ident["den"]):
            _fail(where, f"{prefix}.num", f"expected at most {len(ident['den'])} coefficients (a proper model, "
                                          "descending powers, as long as den at most)")
    if kind == "published_z":
        _numbers(where, f"{prefix}.input_offsets", ident.setdefault("input_offsets", [0.0]), what="input offsets")
    if kind == "physical_fit":
        _check_choice(where, f"{prefix}.model_effects", ident.setdefault("model_effects", "scenario"),
                      ("scenario", "none"))
        if ident.get("fit_starts", 1) < 1:
            _fail(where, f"{prefix}.fit_starts", f"expected a positive integer, got {ident['fit_starts']!r}")
    if kind == "published_s":
        units = ident.setdefault("time_units", ["s"])
        if not units:
            _fail(where, f"{prefix}.time_units", f"expected a non-empty list of {', '.join(TIME_UNITS)}")
        for u in units:
            _check_choice(where, f"{prefix}.time_units", u, TIME_UNITS)
        if ident.setdefault("delay", 0.0) < 0:
            _fail(where, f"{prefix}.delay", f"expected a delay >= 0, got {ident['delay']!r}")
    ident.setdefault("enabled", True)


def _validate_with_rig(where, data, variant_exps):
    """What needs the rig: its name, the overrides, the effects, the sample count, units and start position."""
    from ..model import parse_effect_text
    from ..rig import load_rig

    try:
        rig = load_rig(data["rig"]["name"])
    except PneusimError as exc:
        _fail(where, "rig.name", str(exc))
    for key, value in data["rig"]["overrides"].items():
        if key not in rig.params:
            _fail(where, f"rig.overrides.{key}", f"unknown parameter of rig {rig.name!r}; expected one of "
                                                 + ", ".join(sorted(rig.params)))
    try:
        rig = rig.with_params(data["rig"]["overrides"])
    except InputFileError as exc:
        _fail(where, f"rig.overrides.{exc.field}" if exc.field else "rig.overrides", exc.reason)
    except PneusimError as exc:
        _fail(where, "rig.overrides", str(exc))
    for i, text in enumerate(data["rig"]["effects"]):
        try:
            parse_effect_text(text)
        except (PneusimError, TypeError, ValueError) as exc:
            _fail(where, f"rig.effects[{i}]", f"{exc} (form: 'NAME:PARAM=VALUE,...')")
    for prefix, exp in [("experiment", data["experiment"])] + list(variant_exps):
        ts = float(exp.get("sample_time_s") or rig.sample_time_s)
        if not exp["duration_s"] / ts <= MAX_SAMPLES + 0.5:
            _fail(where, f"{prefix}.duration_s", f"expected at most {MAX_SAMPLES} samples ({MAX_SAMPLES * ts:g} s at "
                                                 f"{ts:g} s, what a recording holds in memory), got "
                                                 f"{exp['duration_s']!r} s")
        n = int(round(exp["duration_s"] / ts))
        if n < MIN_SAMPLES:
            _fail(where, f"{prefix}.duration_s", f"expected at least {MIN_SAMPLES} samples: {exp['duration_s']!r} s "
                                                 f"at {ts:g} s gives {n}")
        unit = exp["signal"].get("unit", "native")
        if exp["loop"] == "open" and unit != "native":
            _fail(where, f"{prefix}.signal.unit", f"expected 'native' (valve command in V) in open loop, got {unit!r} "
                                                  "(m and sensor_V are units of a closed-loop reference)")
        x0 = exp.get("initial_position_m")
        if x0 is not None and not 0.0 <= x0 <= rig.stroke_m:
            _fail(where, f"{prefix}.initial_position_m", f"expected a position in [0, {rig.stroke_m:g}] m "
                                                         f"(the stroke of {rig.name}), got {x0!r}")


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
    if parts[0] not in set(_TABLES) | {"identifiers", "variants", "rig_variants", "conditions"}:
        raise InputFileError(f"cannot vary {key!r}: unknown scenario table {parts[0]!r}", path=where, field=key)
    node = data
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            try:
                node = node[int(part)]
            except (ValueError, IndexError):
                raise InputFileError(f"cannot vary {key!r}: no list item {part!r} (the list has {len(node)})",
                                     path=where, field=key) from None
        elif isinstance(node, dict):
            node = node.setdefault(part, {})
        else:
            raise InputFileError(f"cannot vary {key!r}: {'.'.join(parts[:i])!r} is not a table",
                                 path=where, field=key)
    last = parts[-1]
    if isinstance(node, list):
        try:
            node[int(last)] = value
        except (ValueError, IndexError):
            raise InputFileError(f"cannot vary {key!r}: no list item {last!r} (the list has {len(node)})",
                                 path=where, field=key) from None
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise InputFileError(f"cannot vary {key!r}: {'.'.join(parts[:-1])!r} is not a table", path=where, field=key)
