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
from ..model import parse_effect_text
from ..online import check_rls_settings
from ..plausibility import check_noise_scale
from ..rig import load_rig
from ..signals import OUTPUT_UNITS, SIGNAL_KINDS, output_scale, validate_signal
from ..simulate import rig_effects
from ..tomlcheck import NUMBER, check_choice, check_keys, check_numbers, check_type, fail
from ..tomlfile import read_toml

__all__ = ["load_scenario", "validate_scenario", "set_dotted", "get_dotted", "SIGNAL_KINDS",
           "IDENTIFIER_KINDS", "OUTPUT_UNITS", "INPUTS", "LAYOUTS", "MIN_SAMPLES"]

IDENTIFIER_KINDS = ("rls", "arx", "armax", "ss", "tf", "published_z", "published_s", "physical_fit")
INPUTS = ("valve_cmd_V", "signal")
LAYOUTS = ("generic", "paper1-table1", "paper2-table1")
TIME_UNITS = ("s", "ms", "sample")
METRIC_NAMES = ("fit_percent", "mse", "rmse", "error_std", "wall_time_s")
#: fewest samples an experiment may have
MIN_SAMPLES = 50

#: allowed keys per table: name -> (types, required, default)
_TABLES: dict[str, dict[str, tuple]] = {
    "scenario": {"name": (str, True, None), "title": (str, False, ""), "description": (str, False, ""),
                 "layout": (str, False, "generic"), "notes": (list, False, [])},
    "rig": {"name": (str, True, None), "overrides": (dict, False, {}), "effects": (list, False, [])},
    "experiment": {"loop": (str, True, None), "duration_s": (NUMBER, True, None), "sample_time_s": (NUMBER, False, None),
                   "seed": (int, False, 0), "noise_scale": (NUMBER, False, 1.0), "warmup_s": (NUMBER, False, 1.0),
                   "initial_position_m": (NUMBER, False, None), "signal": (dict, True, None),
                   "controller": (dict, False, {})},
    "data": {"output_unit": (str, False, "m"), "output_offset": (NUMBER, False, 0.0),
             "input": (str, False, "valve_cmd_V"), "input_offset": (NUMBER, False, 0.0),
             "estimation_fraction": (NUMBER, False, 0.5)},
    "metrics": {"report": (list, False, ["fit_percent", "mse"])},
}
_CONTROLLER_KEYS = {"kind": str, "kp_V_per_m": NUMBER, "u0_V": NUMBER, "u_min_V": NUMBER, "u_max_V": NUMBER}
_IDENT_KEYS = {"name": str, "kind": str, "orders": list, "order": int, "forgetting": NUMBER,
               "initial_covariance": NUMBER, "horizons": list, "nx": int, "np": int, "nz": int,
               "iodelay_s": NUMBER, "num": list, "den": list, "time_units": list, "delay": NUMBER, "published": dict,
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


def validate_scenario(data: dict, where: str = "scenario") -> dict:
    """Check every table and key of a scenario dict; return a deep copy with defaults filled in."""
    data = copy.deepcopy(data)
    unknown = sorted(set(data) - set(_TABLES) - {"identifiers", "variants", "rig_variants", "conditions"})
    if unknown:
        fail(where, unknown[0], f"unknown table; expected one of {', '.join(sorted(_TABLES))}, identifiers, "
                                 "variants, rig_variants, conditions")
    for table, keys in _TABLES.items():
        given = data.setdefault(table, {})
        if not isinstance(given, dict):
            fail(where, table, "expected a table")
        check_keys(where, table, given, keys)
        for key, (types, required, default) in keys.items():
            if key not in given:
                if required:
                    fail(where, f"{table}.{key}", "required key missing")
                given[key] = copy.deepcopy(default)
            elif given[key] is not None:
                check_type(where, f"{table}.{key}", given[key], types)
    for i, note in enumerate(data["scenario"]["notes"]):
        check_type(where, f"scenario.notes[{i}]", note, str)
    check_choice(where, "scenario.layout", data["scenario"]["layout"], LAYOUTS)
    check_choice(where, "data.output_unit", data["data"]["output_unit"], OUTPUT_UNITS)
    check_choice(where, "data.input", data["data"]["input"], INPUTS)
    for key, value in data["rig"]["overrides"].items():
        check_type(where, f"rig.overrides.{key}", value, NUMBER)
    for i, eff in enumerate(data["rig"]["effects"]):
        check_type(where, f"rig.effects[{i}]", eff, str)
    exp = data["experiment"]
    _validate_experiment(where, exp, "experiment")
    frac = data["data"]["estimation_fraction"]
    if not 0.0 < frac < 1.0:
        fail(where, "data.estimation_fraction", f"expected a number in (0, 1), got {frac!r}")
    for m in data["metrics"]["report"]:
        check_choice(where, "metrics.report", m, METRIC_NAMES)
    idents = data.setdefault("identifiers", [])
    if not isinstance(idents, list) or not idents:
        fail(where, "identifiers", "expected at least one [[identifiers]] table")
    names = set()
    for i, ident in enumerate(idents):
        _validate_identifier(where, f"identifiers[{i}]", ident)
        if ident["name"] in names:
            fail(where, f"identifiers[{i}].name", f"duplicate identifier name {ident['name']!r}")
        names.add(ident["name"])
    variants = data.setdefault("variants", [])
    if not isinstance(variants, list):
        fail(where, "variants", "expected [[variants]] tables")
    merged_exps = []
    for i, var in enumerate(variants):
        if not isinstance(var, dict) or not isinstance(var.get("name"), str):
            fail(where, f"variants[{i}].name", "expected a table with a string 'name'")
        check_keys(where, f"variants[{i}]", var, ("name", "description", "experiment"))
        vexp = var.get("experiment", {})
        if not isinstance(vexp, dict):
            fail(where, f"variants[{i}].experiment", "expected a table of [experiment] keys")
        prefix = f"variants[{i}].experiment"
        check_keys(where, prefix, vexp, _TABLES["experiment"])
        for key, value in vexp.items():
            if value is not None:
                check_type(where, f"{prefix}.{key}", value, _TABLES["experiment"][key][0])
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
        fail(where, key, f"expected [[{key}]] tables")
    names = set()
    for i, item in enumerate(items):
        check_keys(where, f"{key}[{i}]", item, keys)
        for k, (types, required, default) in keys.items():
            if k not in item:
                if required:
                    fail(where, f"{key}[{i}].{k}", "required key missing")
                item[k] = copy.deepcopy(default)
            else:
                check_type(where, f"{key}[{i}].{k}", item[k], types)
        if item["name"] in names:
            fail(where, f"{key}[{i}].name", f"duplicate name {item['name']!r}")
        names.add(item["name"])
    return items


def _validate_rig_variants(where, data):
    """``[[rig_variants]]``: the rig loads (shipped name or file), the effects parse."""
    for i, var in enumerate(_list_of_tables(where, data, "rig_variants", _RIG_VARIANT_KEYS)):
        try:
            rig_effects(load_rig(var["rig"]))
        except PneusimError as exc:
            fail(where, f"rig_variants[{i}].rig", str(exc))
        for j, text in enumerate(var["effects"]):
            check_type(where, f"rig_variants[{i}].effects[{j}]", text, str)
            try:
                parse_effect_text(text)
            except (PneusimError, TypeError, ValueError) as exc:
                fail(where, f"rig_variants[{i}].effects[{j}]", f"{exc} (form: 'NAME:PARAM=VALUE,...')")


def _validate_conditions(where, data):
    """``[[conditions]]``: rig overrides the rig has (with possible values) and a valid merged experiment."""
    conds = _list_of_tables(where, data, "conditions", _CONDITION_KEYS)
    if not conds:
        return
    rig = load_rig(data["rig"]["name"]).with_params(data["rig"]["overrides"])
    for i, cond in enumerate(conds):
        prefix = f"conditions[{i}]"
        for key, value in cond["rig_overrides"].items():
            check_type(where, f"{prefix}.rig_overrides.{key}", value, NUMBER)
            if key not in rig.params:
                fail(where, f"{prefix}.rig_overrides.{key}", f"unknown parameter of rig {rig.name!r}")
        try:
            rig.with_params(cond["rig_overrides"])
        except PneusimError as exc:
            fail(where, f"{prefix}.rig_overrides", getattr(exc, "reason", str(exc)))
        cexp = cond["experiment"]
        check_keys(where, f"{prefix}.experiment", cexp, _TABLES["experiment"])
        for key, value in cexp.items():
            check_type(where, f"{prefix}.experiment.{key}", value, _TABLES["experiment"][key][0])
        merged = copy.deepcopy(data["experiment"])
        merged.update(copy.deepcopy(cexp))
        _validate_experiment(where, merged, f"{prefix}.experiment")


def _validate_experiment(where, exp, prefix):
    """The [experiment] table (or a variant's merged copy): values, controller and signal."""
    check_choice(where, f"{prefix}.loop", exp["loop"], ("open", "closed"))
    if not 0 < exp["duration_s"] < float("inf"):
        fail(where, f"{prefix}.duration_s", f"expected a positive finite duration in s, got {exp['duration_s']!r}")
    if exp.get("sample_time_s") is not None and not 0 < exp["sample_time_s"] < float("inf"):
        fail(where, f"{prefix}.sample_time_s", f"expected a positive sample time in s, got {exp['sample_time_s']!r}")
    for key in ("noise_scale", "warmup_s", "seed"):
        if exp.get(key) is not None and not (exp[key] >= 0 and exp[key] < float("inf")):   # NaN fails too
            fail(where, f"{prefix}.{key}", f"expected a finite number >= 0, got {exp[key]!r}")
    ctrl = exp.get("controller") or {}
    check_keys(where, f"{prefix}.controller", ctrl, _CONTROLLER_KEYS)
    for key, value in ctrl.items():
        check_type(where, f"{prefix}.controller.{key}", value, _CONTROLLER_KEYS[key])
    if "kind" in ctrl:
        check_choice(where, f"{prefix}.controller.kind", ctrl["kind"], ("proportional",))
    if "kp_V_per_m" in ctrl and not ctrl["kp_V_per_m"] > 0:
        fail(where, f"{prefix}.controller.kp_V_per_m", f"expected a positive gain in V/m, got {ctrl['kp_V_per_m']!r}")
    validate_signal(where, exp["signal"], f"{prefix}.signal")


def _validate_identifier(where, prefix, ident):
    if not isinstance(ident, dict):
        fail(where, prefix, "expected a table")
    check_keys(where, prefix, ident, _IDENT_KEYS)
    for key, value in ident.items():
        check_type(where, f"{prefix}.{key}", value, _IDENT_KEYS[key])
    for key in ("name", "kind"):
        if key not in ident:
            fail(where, f"{prefix}.{key}", "required key missing")
    kind = ident["kind"]
    check_choice(where, f"{prefix}.kind", kind, IDENTIFIER_KINDS)
    check_keys(where, prefix, ident, _IDENT_COMMON + _IDENT_KIND_KEYS[kind], context=f" for kind = {kind!r}")
    need = {"rls": ("order",), "arx": ("orders",), "armax": ("orders",), "ss": ("nx",), "tf": ("np", "nz"),
            "published_z": ("num", "den"), "published_s": ("num", "den")}.get(kind, ())
    for key in need:
        if key not in ident:
            fail(where, f"{prefix}.{key}", f"required for kind = {kind!r}")
    for key, value in ident.get("published", {}).items():
        check_type(where, f"{prefix}.published.{key}", value, NUMBER)
    n_orders = {"arx": 3, "armax": 4}.get(kind)
    if n_orders and (len(ident["orders"]) != n_orders
                     or not all(isinstance(o, int) and not isinstance(o, bool) and o >= 0 for o in ident["orders"])):
        fail(where, f"{prefix}.orders", f"expected {n_orders} non-negative integers for {kind}, got {ident['orders']!r}")
    if kind == "rls":
        if ident["order"] < 1:
            fail(where, f"{prefix}.order", f"expected a positive integer, got {ident['order']!r}")
        lam = ident.setdefault("forgetting", 0.99)
        if not 0.0 < lam <= 1.0:
            fail(where, f"{prefix}.forgetting", f"expected a number in (0, 1], got {lam!r}")
        if not ident.setdefault("initial_covariance", 1000.0) > 0:
            fail(where, f"{prefix}.initial_covariance", "expected a positive number")
        check_choice(where, f"{prefix}.engine", ident.setdefault("engine", "auto"), ("auto", "sysid", "pneusim"))
        hs = ident.setdefault("horizons", [1])
        if not hs or not all(isinstance(h, int) and not isinstance(h, bool) and h >= 1 for h in hs):
            fail(where, f"{prefix}.horizons", f"expected a list of positive integers (prediction steps), got {hs!r}")
    if kind == "ss" and ident["nx"] < 1:
        fail(where, f"{prefix}.nx", f"expected a positive integer, got {ident['nx']!r}")
    if kind == "tf":
        if ident["np"] < 1:
            fail(where, f"{prefix}.np", f"expected a positive integer, got {ident['np']!r}")
        if not 0 <= ident["nz"] <= ident["np"]:
            fail(where, f"{prefix}.nz", f"expected an integer in [0, np = {ident['np']}], got {ident['nz']!r}")
        if ident.get("iodelay_s", 0.0) < 0:
            fail(where, f"{prefix}.iodelay_s", f"expected a delay >= 0 in s, got {ident['iodelay_s']!r}")
    if kind in ("published_z", "published_s"):
        check_numbers(where, f"{prefix}.num", ident["num"])
        check_numbers(where, f"{prefix}.den", ident["den"])
        if ident["den"][0] == 0:
            fail(where, f"{prefix}.den", "expected a non-zero leading coefficient (descending powers)")
        if len(ident["num"]) > len(ident["den"]):
            fail(where, f"{prefix}.num", f"expected at most {len(ident['den'])} coefficients (a proper model, "
                                          "descending powers, as long as den at most)")
    if kind == "published_z":
        check_numbers(where, f"{prefix}.input_offsets", ident.setdefault("input_offsets", [0.0]), what="input offsets")
    if kind == "physical_fit":
        check_choice(where, f"{prefix}.model_effects", ident.setdefault("model_effects", "scenario"),
                      ("scenario", "none"))
        if ident.get("fit_starts", 1) < 1:
            fail(where, f"{prefix}.fit_starts", f"expected a positive integer, got {ident['fit_starts']!r}")
    if kind == "published_s":
        units = ident.setdefault("time_units", ["s"])
        if not units:
            fail(where, f"{prefix}.time_units", f"expected a non-empty list of {', '.join(TIME_UNITS)}")
        for u in units:
            check_choice(where, f"{prefix}.time_units", u, TIME_UNITS)
        if ident.setdefault("delay", 0.0) < 0:
            fail(where, f"{prefix}.delay", f"expected a delay >= 0, got {ident['delay']!r}")
    ident.setdefault("enabled", True)


def _validate_with_rig(where, data, variant_exps):
    """What needs the rig: its name, the overrides, the effects, the sample count, units and start position."""
    try:
        rig = load_rig(data["rig"]["name"])
        rig_effects(rig)
    except PneusimError as exc:
        fail(where, "rig.name", str(exc))
    for key, value in data["rig"]["overrides"].items():
        if key not in rig.params:
            fail(where, f"rig.overrides.{key}", f"unknown parameter of rig {rig.name!r}; expected one of "
                                                 + ", ".join(sorted(rig.params)))
    try:
        rig = rig.with_params(data["rig"]["overrides"])
    except InputFileError as exc:
        fail(where, f"rig.overrides.{exc.field}" if exc.field else "rig.overrides", exc.reason)
    except PneusimError as exc:
        fail(where, "rig.overrides", str(exc))
    for i, text in enumerate(data["rig"]["effects"]):
        try:
            parse_effect_text(text)
        except (PneusimError, TypeError, ValueError) as exc:
            fail(where, f"rig.effects[{i}]", f"{exc} (form: 'NAME:PARAM=VALUE,...')")
    for prefix, exp in [("experiment", data["experiment"])] + list(variant_exps):
        ts = float(exp.get("sample_time_s") or rig.sample_time_s)
        if not exp["duration_s"] / ts <= MAX_SAMPLES + 0.5:
            fail(where, f"{prefix}.duration_s", f"expected at most {MAX_SAMPLES} samples ({MAX_SAMPLES * ts:g} s at "
                                                 f"{ts:g} s, what a recording holds in memory), got "
                                                 f"{exp['duration_s']!r} s")
        n = int(round(exp["duration_s"] / ts))
        if n < MIN_SAMPLES:
            fail(where, f"{prefix}.duration_s", f"expected at least {MIN_SAMPLES} samples: {exp['duration_s']!r} s "
                                                 f"at {ts:g} s gives {n}")
        unit = exp["signal"].get("unit", "native")
        if exp["loop"] == "open" and unit != "native":
            fail(where, f"{prefix}.signal.unit", f"expected 'native' (valve command in V) in open loop, got {unit!r} "
                                                  "(m and sensor_V are units of a closed-loop reference)")
        x0 = exp.get("initial_position_m")
        if x0 is not None and not 0.0 <= x0 <= rig.stroke_m:
            fail(where, f"{prefix}.initial_position_m", f"expected a position in [0, {rig.stroke_m:g}] m "
                                                         f"(the stroke of {rig.name}), got {x0!r}")
        try:
            check_noise_scale(rig, float(exp.get("noise_scale", 1.0)), f"{prefix}.noise_scale")
        except PneusimError as exc:
            fail(where, f"{prefix}.noise_scale", str(exc).partition(": ")[2])
        if prefix == "experiment":
            _validate_online_identifiers(where, data, rig, n)


def _validate_online_identifiers(where, data, rig, n_samples: int) -> None:
    """The online (``rls``) identifiers against the run: horizons shorter than it, and the forgetting factor and
    initial covariance against the signals they will see (:func:`sysid.check_rls_options`, the checks of
    :class:`sysid.RecursiveARX`: ``forgetting = 1e-300`` or ``initial_covariance = 1e308`` give no estimate)."""
    d = data["data"]
    scale, y_off, u_off = output_scale(rig, d["output_unit"]), float(d["output_offset"]), float(d["input_offset"])
    y_max = max(abs(y_off), abs(rig.stroke_m * scale - y_off))
    u_max = (max(abs(rig.params["valve_min_V"] - u_off), abs(rig.params["valve_max_V"] - u_off))
             if d["input"] == "valve_cmd_V" else None)
    for i, ident in enumerate(data["identifiers"]):
        if ident["kind"] != "rls":
            continue
        check_rls_settings(where, f"identifiers[{i}]", ident, n_samples, y_max, u_max)


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
