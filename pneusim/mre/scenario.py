"""MRE files: which plant, controller, reference and online identifiers run in the loop.

An MRE file is TOML (schema below and in the README section "Mixed-reality environment"; example
``scenarios/mre-paper1.toml``)::

    [mre]        name, title, description, plant ("sim"), mode ("fast" | "realtime"), duration_s,
                 warmup_s, seed, noise_scale, overrun_budget (fraction of samples), status_interval_s,
                 udp_reply_timeout_s
    [rig]        name, overrides, effects                       (as in scenario files)
    [controller] kind = "proportional" | "pid" | "none" (open loop) and its gains
    [reference]  kind = "pulses" | "steps" | "multisine" | "doublets" ...  (a scenario signal)
    [data]       output_unit, output_offset, input_offset        (what the identifiers see)
    [[identifiers]] name, kind = "rls" (paper 1 eq. 8) | "recursive_arx" (sysid.RecursiveARX),
                 order, forgetting, initial_covariance, horizons

Every mistake is refused with one line naming the file, the key and what was expected; what needs the
rig is checked when the components are built (:func:`build_components`), before the loop starts: the
start position within the stroke, a noise scale the recording can hold, prediction horizons within the
run, and each identifier's forgetting factor and initial covariance against the signals it will see
(:func:`sysid.check_rls_options`: settings that cannot give an estimate, e.g. ``forgetting = 1e-300`` or
``initial_covariance = 1e308``, would end in ``G(z) = (nan ...)``).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..controller import PIDController, ProportionalController
from ..errors import InputFileError, PneusimError
from ..experiment import MAX_SAMPLES
from ..online import PaperRLS, SysidRLS, check_rls_settings
from ..plausibility import check_noise_scale
from ..rig import load_rig
from ..signals import OUTPUT_UNITS, build_signal, output_scale, sensor_gain, validate_signal
from ..simulate import merged_effects
from ..tomlcheck import fail
from ..tomlfile import read_toml
from .daq import daq_config
from .plants import PLANT_KINDS, parse_plant

__all__ = ["load_mre", "validate_mre", "MRE_MODES", "Components", "build_components", "build_controller",
           "build_reference", "build_estimators", "check_identifiers"]

MRE_MODES = ("fast", "realtime")
_NUM = (int, float)
_TABLES = {
    "mre": {"name": (str, True, None), "title": (str, False, ""), "description": (str, False, ""),
            "plant": (str, False, "sim"), "mode": (str, False, "fast"), "duration_s": (_NUM, True, None),
            "warmup_s": (_NUM, False, 1.0), "seed": (int, False, 0), "noise_scale": (_NUM, False, 1.0),
            "overrun_budget": (_NUM, False, 0.01), "status_interval_s": (_NUM, False, 0.5),
            "udp_reply_timeout_s": (_NUM, False, None), "initial_position_m": (_NUM, False, None),
            "notes": (list, False, [])},
    "rig": {"name": (str, True, None), "overrides": (dict, False, {}), "effects": (list, False, [])},
    "controller": {"kind": (str, True, None), "kp_V_per_m": (_NUM, False, None), "ki_V_per_m_s": (_NUM, False, 0.0),
                   "kd_V_s_per_m": (_NUM, False, 0.0), "derivative_filter_s": (_NUM, False, 0.0),
                   "u0_V": (_NUM, False, None), "u_min_V": (_NUM, False, None), "u_max_V": (_NUM, False, None)},
    "data": {"output_unit": (str, False, "cm"), "output_offset": (_NUM, False, 0.0),
             "input_offset": (_NUM, False, 0.0)},
}
_IDENT = {"name": (str, True, None), "kind": (str, True, None), "order": (int, True, None),
          "forgetting": (_NUM, False, 0.99), "initial_covariance": (_NUM, False, 1000.0),
          "horizons": (list, False, [1]), "note": (str, False, "")}
IDENT_KINDS = ("rls", "recursive_arx")
CONTROLLER_KINDS = ("proportional", "pid", "none")


def _typed(where, key, value, types):
    allowed = types if isinstance(types, tuple) else (types,)
    if (isinstance(value, bool) and bool not in allowed) or not isinstance(value, allowed):
        names = {int: "an integer", str: "a string", list: "a list", dict: "a table"}
        fail(where, key, f"expected {'a number' if types == _NUM else names.get(types, str(types))}, got {value!r}")
    if types == _NUM and not math.isfinite(value):
        fail(where, key, f"expected a finite number, got {value!r}")


def _table(where, prefix, given, spec):
    if not isinstance(given, dict):
        fail(where, prefix, "expected a table")
    for key in sorted(set(given) - set(spec)):
        fail(where, f"{prefix}.{key}", f"unknown key; expected one of {', '.join(spec)}")
    out = {}
    for key, (types, required, default) in spec.items():
        if key not in given:
            if required:
                fail(where, f"{prefix}.{key}", "required key missing")
            out[key] = copy.deepcopy(default)
            continue
        _typed(where, f"{prefix}.{key}", given[key], types)
        out[key] = given[key]
    return out


def load_mre(path) -> dict:
    """Read and check an MRE file; returns the checked dict with defaults filled in."""
    path = Path(path)
    if path.suffix.lower() != ".toml":
        raise InputFileError("expected an MRE file (.toml)", path=path)
    data = read_toml(path, "MRE")
    rig = data.get("rig")
    if isinstance(rig, dict) and isinstance(rig.get("name"), str) and rig["name"].endswith(".toml") \
            and not Path(rig["name"]).is_absolute():
        rig["name"] = str((path.parent / rig["name"]).resolve())
    return validate_mre(data, str(path))


def validate_mre(data: dict, where: str = "MRE file") -> dict:
    """Check every table and key of an MRE dict (see the module docstring)."""
    allowed = set(_TABLES) | {"reference", "identifiers"}
    for key in sorted(set(data) - allowed):
        fail(where, key, f"unknown table; expected one of {', '.join(sorted(allowed))}")
    for key in ("mre", "rig", "controller", "reference"):
        if key not in data:
            fail(where, key, "required table missing")
    out = {name: _table(where, name, data.get(name, {}), spec) for name, spec in _TABLES.items()}
    _check_run(where, out["mre"])
    for i, eff in enumerate(out["rig"]["effects"]):
        if not isinstance(eff, str):
            fail(where, f"rig.effects[{i}]", f"expected an effect text NAME[:PARAM=VALUE,...], got {eff!r}")
    _check_controller(where, out["controller"], data["controller"])
    out["reference"] = _checked_reference(where, data["reference"], out["controller"]["kind"])
    d = out["data"]
    if d["output_unit"] not in OUTPUT_UNITS:
        fail(where, "data.output_unit", f"expected one of {', '.join(OUTPUT_UNITS)}, got {d['output_unit']!r}")
    out["identifiers"] = _checked_identifiers(where, data.get("identifiers", []))
    out["source"] = where
    return out


def _check_run(where, m: dict) -> None:
    """The ``[mre]`` table's values: mode, plant, times, seed, noise, overrun budget."""
    if m["mode"] not in MRE_MODES:
        fail(where, "mre.mode", f"expected one of {', '.join(MRE_MODES)}, got {m['mode']!r}")
    try:
        parse_plant(m["plant"])
    except PneusimError:
        fail(where, "mre.plant", f"expected one of {', '.join(PLANT_KINDS)}, got {m['plant']!r}")
    for key in ("duration_s", "status_interval_s"):
        if not m[key] > 0:
            fail(where, f"mre.{key}", f"expected a positive time in s, got {m[key]!r}")
    for key in ("warmup_s", "noise_scale", "seed"):
        if m[key] < 0:
            fail(where, f"mre.{key}", f"expected a number >= 0, got {m[key]!r}")
    if not 0 <= m["overrun_budget"] <= 1:
        fail(where, "mre.overrun_budget", f"expected a fraction of samples in [0, 1], got {m['overrun_budget']!r}")
    if m["udp_reply_timeout_s"] is not None and not m["udp_reply_timeout_s"] > 0:
        fail(where, "mre.udp_reply_timeout_s", f"expected a positive time in s, got {m['udp_reply_timeout_s']!r}")


def _check_controller(where, c: dict, given: dict) -> None:
    """The ``[controller]`` table: its kind and the gains that kind takes (``given``: the table as written)."""
    if c["kind"] not in CONTROLLER_KINDS:
        fail(where, "controller.kind", f"expected one of {', '.join(CONTROLLER_KINDS)}, got {c['kind']!r}")
    if c["kind"] != "none":
        if c["kp_V_per_m"] is None:
            fail(where, "controller.kp_V_per_m", "required key missing")
        if not c["kp_V_per_m"] > 0:
            fail(where, "controller.kp_V_per_m", f"expected a positive gain in V/m, got {c['kp_V_per_m']!r}")
    if c["kind"] == "proportional":
        for key in ("ki_V_per_m_s", "kd_V_s_per_m", "derivative_filter_s"):
            if key in given:
                fail(where, f"controller.{key}", "only for kind = 'pid'")
    for key in ("ki_V_per_m_s", "kd_V_s_per_m", "derivative_filter_s"):
        if c[key] < 0:
            fail(where, f"controller.{key}", f"expected a number >= 0, got {c[key]!r}")


def _checked_reference(where, given, controller_kind: str) -> dict:
    """The ``[reference]`` table, a signal (:func:`pneusim.signals.validate_signal`); in open loop a valve command."""
    ref = copy.deepcopy(given)
    if not isinstance(ref, dict):
        fail(where, "reference", "expected a table")
    validate_signal(where, ref, "reference")
    if controller_kind == "none" and ref.get("unit", "native") != "native":
        fail(where, "reference.unit", "open loop (controller.kind = 'none'): the reference is the valve command "
                                      "in V; expected unit = 'native'")
    return ref


def _checked_identifiers(where, idents) -> list[dict]:
    """The ``[[identifiers]]`` tables: kind, order, forgetting, covariance, horizons, unique names."""
    if not isinstance(idents, list):
        fail(where, "identifiers", "expected [[identifiers]] tables")
    out, names = [], set()
    for i, ident in enumerate(idents):
        prefix = f"identifiers[{i}]"
        it = _table(where, prefix, ident, _IDENT)
        if it["kind"] not in IDENT_KINDS:
            fail(where, f"{prefix}.kind", f"expected one of {', '.join(IDENT_KINDS)}, got {it['kind']!r}")
        if not 1 <= it["order"] <= 20:
            fail(where, f"{prefix}.order", f"expected an order in 1..20, got {it['order']!r}")
        if not 0 < it["forgetting"] <= 1:
            fail(where, f"{prefix}.forgetting", f"expected a forgetting factor in (0, 1], got {it['forgetting']!r}")
        if not it["initial_covariance"] > 0:
            fail(where, f"{prefix}.initial_covariance", f"expected a number > 0, got {it['initial_covariance']!r}")
        h = it["horizons"]
        if not h or not all(isinstance(x, int) and not isinstance(x, bool) and x >= 1 for x in h):
            fail(where, f"{prefix}.horizons", f"expected a non-empty list of whole numbers >= 1, got {h!r}")
        if it["name"] in names:
            fail(where, f"{prefix}.name", f"identifier name {it['name']!r} used twice")
        names.add(it["name"])
        out.append(it)
    return out


@dataclass
class Components:
    """What an MRE file builds: rig, effects, reference, controller, estimators and conversions."""

    rig: object
    effects: list
    reference: np.ndarray
    controller: object
    estimators: dict
    to_output: object
    to_input: object
    n_warm: int
    x0_m: float
    u_init_V: float
    output_unit: str


def build_controller(c: dict, rig):
    """The controller of a checked ``[controller]`` table (``None`` for open loop)."""
    if c["kind"] == "none":
        return None
    p = rig.params
    u0 = p["valve_null_V"] if c["u0_V"] is None else c["u0_V"]
    lo = p["valve_min_V"] if c["u_min_V"] is None else c["u_min_V"]
    hi = p["valve_max_V"] if c["u_max_V"] is None else c["u_max_V"]
    if c["kind"] == "proportional":
        return ProportionalController(float(c["kp_V_per_m"]), float(u0), float(lo), float(hi))
    return PIDController(float(c["kp_V_per_m"]), float(c["ki_V_per_m_s"]), float(c["kd_V_s_per_m"]),
                         rig.sample_time_s, float(u0), float(lo), float(hi), float(c["derivative_filter_s"]))


def build_reference(spec: dict, rig, n: int, seed: int, closed: bool) -> np.ndarray:
    """The reference (m closed loop, V open loop), shape (n,)."""
    raw = build_signal(spec, n, rig.sample_time_s, seed)
    if closed and spec.get("unit") == "sensor_V":
        return raw / sensor_gain(rig)
    return raw


def build_estimators(idents: list[dict]) -> dict:
    """``{name: estimator}``: ``rls`` is paper 1's eq. 8 (:class:`PaperRLS`), ``recursive_arx`` runs
    :class:`sysid.RecursiveARX` ``([n, n, 1])`` inside the loop."""
    out = {}
    for it in idents:
        cls = PaperRLS if it["kind"] == "rls" else SysidRLS
        out[it["name"]] = cls(it["order"], it["forgetting"], it["initial_covariance"], tuple(it["horizons"]))
    return out


def build_components(spec: dict, duration_s: float | None = None) -> Components:
    """Everything the loop needs from a checked MRE dict (``duration_s`` overrides ``mre.duration_s``)."""
    m = spec["mre"]
    rig = load_rig(spec["rig"]["name"])
    daq_config(rig)                        # a bad [daq] section is refused whatever the plant
    if spec["rig"]["overrides"]:
        rig = rig.with_params(spec["rig"]["overrides"], origin="rig.overrides")
    effects = merged_effects(rig, spec["rig"]["effects"])
    ts = rig.sample_time_s
    duration = float(duration_s if duration_s is not None else m["duration_s"])
    if not duration / ts <= MAX_SAMPLES + 0.5:
        raise PneusimError(f"duration {duration:g} s gives {duration / ts:.4g} samples at {ts:g} s; at most "
                           f"{MAX_SAMPLES} ({MAX_SAMPLES * ts:g} s) fit in memory as a recording")
    n = int(round(duration / ts))
    if n < 50:
        raise PneusimError(f"duration {duration:g} s gives {n} samples at {ts:g} s; at least 50 are needed")
    ctrl = build_controller(spec["controller"], rig)
    closed = ctrl is not None
    ref = build_reference(spec["reference"], rig, n, int(m["seed"]), closed)
    d = spec["data"]
    unit = d["output_unit"]
    scale = output_scale(rig, unit)
    y_off, u_off = float(d["output_offset"]), float(d["input_offset"])
    where = spec.get("source", "MRE file")
    x0 = m["initial_position_m"]
    if x0 is None:
        x0 = float(np.clip(ref[0], 0.0, rig.stroke_m)) if closed else 0.5 * rig.stroke_m
    elif not 0.0 <= x0 <= rig.stroke_m:
        fail(where, "mre.initial_position_m", f"expected a position in [0, {rig.stroke_m:g}] m (the stroke of "
                                              f"{rig.name}), got {x0!r}")
    try:
        check_noise_scale(rig, float(m["noise_scale"]), "mre.noise_scale")
    except PneusimError as exc:
        fail(where, "mre.noise_scale", str(exc).partition(": ")[2])
    if not float(m["warmup_s"]) / ts <= MAX_SAMPLES + 0.5:
        raise PneusimError(f"mre.warmup_s = {m['warmup_s']:g} s gives {m['warmup_s'] / ts:.4g} samples at {ts:g} s; "
                           f"at most {MAX_SAMPLES} ({MAX_SAMPLES * ts:g} s)")
    n_warm = int(round(float(m["warmup_s"]) / ts))
    u_init = ctrl.command(-n_warm * ts, ref[0], x0) if closed else float(ref[0])
    if closed:
        ctrl.reset()
    y_max = max(abs(0.0 * scale - y_off), abs(rig.stroke_m * scale - y_off))
    u_range = [rig.params["valve_min_V"], rig.params["valve_max_V"]] + ([] if closed else [float(np.min(ref)),
                                                                                         float(np.max(ref))])
    u_max = max(abs(u - u_off) for u in u_range)
    check_identifiers(where, spec["identifiers"], n, y_max, u_max)
    return Components(rig, effects, ref, ctrl, build_estimators(spec["identifiers"]),
                      lambda p: p * scale - y_off, lambda u, k: u - u_off, n_warm, float(x0), float(u_init), unit)


def check_identifiers(where: str, idents: list[dict], n_samples: int, max_abs_y: float, max_abs_u: float) -> None:
    """Each identifier's settings against the run: horizons within its ``n_samples`` samples, and its forgetting
    factor and initial covariance against signals up to ``max_abs_y`` and ``max_abs_u`` (identifier units), by
    :func:`sysid.check_rls_options` -- the checks of :class:`sysid.RecursiveARX`, the same recursion."""
    for i, it in enumerate(idents):
        check_rls_settings(where, f"identifiers[{i}]", it, n_samples, max_abs_y, max_abs_u)
