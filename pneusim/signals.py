"""Signals from their descriptions: the excitation of a scenario or the reference of an MRE run, the
experiment around it, and the data the identifiers see.

A signal is a table (``[experiment.signal]`` of a scenario, ``[reference]`` of an MRE file) with a
``kind`` (``multisine``, ``pulses``, ``steps``, ``doublets``) and its keys; :func:`validate_signal`
checks it, :func:`build_signal` samples it.

Signal units (``unit``):

* ``native``: volts of valve command in open loop, metres of reference in closed loop;
* ``m``: metres (closed-loop reference only);
* ``sensor_V``: volts of the rig's position sensor (``position_sensor_V_per_m``); a
  closed-loop reference is converted to metres, ``ref_m = signal_V / k_sensor``.

``offset`` is added to the generated signal in the signal's own unit.
"""

from __future__ import annotations

import numpy as np

from .controller import ProportionalController
from .errors import PneusimError
from .experiment import DEFAULT_KP_V_PER_M, Experiment, command_doublets, multisine, pulse_train, random_steps
from .rig import Rig
from .tomlcheck import NUMBER, check_choice, check_keys, check_numbers, check_type, fail

__all__ = ["build_signal", "validate_signal", "build_experiment", "output_signal", "input_signal", "output_scale",
           "sensor_gain", "OUTPUT_SCALE", "OUTPUT_UNITS", "SIGNAL_KINDS", "SIGNAL_UNITS"]

SIGNAL_KINDS = ("multisine", "pulses", "steps", "doublets")
SIGNAL_UNITS = ("native", "m", "sensor_V")
#: output unit -> metres to unit factor (``sensor_V`` uses the rig's sensor gain)
OUTPUT_SCALE = {"m": 1.0, "cm": 100.0, "mm": 1000.0}
#: units of the identifiers' output
OUTPUT_UNITS = ("m", "cm", "mm", "sensor_V")

#: keys of a signal table and their types
_SIGNAL_KEYS = {"kind": str, "unit": str, "offset": NUMBER, "components": list, "base": NUMBER, "amplitude": list,
                "width_s": list, "rest_s": list, "sign": str, "low": NUMBER, "high": NUMBER, "hold_s": list,
                "half_s": list, "seed": int, "note": str}
_SIGNAL_COMMON = ("kind", "unit", "offset", "seed", "note")
_SIGNAL_KIND_KEYS = {"multisine": ("components",), "pulses": ("base", "amplitude", "width_s", "rest_s", "sign"),
                     "steps": ("low", "high", "hold_s"), "doublets": ("amplitude", "half_s", "rest_s")}


def validate_signal(where, sig: dict, prefix: str = "experiment.signal") -> None:
    """Check a signal table in place (``unit`` defaults to ``native``); a fault names ``where`` and the key."""
    check_keys(where, prefix, sig, _SIGNAL_KEYS)
    for key, value in sig.items():
        check_type(where, f"{prefix}.{key}", value, _SIGNAL_KEYS[key])
    if "kind" not in sig:
        fail(where, f"{prefix}.kind", "required key missing")
    check_choice(where, f"{prefix}.kind", sig["kind"], SIGNAL_KINDS)
    check_keys(where, prefix, sig, _SIGNAL_COMMON + _SIGNAL_KIND_KEYS[sig["kind"]],
               context=f" for kind = {sig['kind']!r}")
    check_choice(where, f"{prefix}.unit", sig.setdefault("unit", "native"), SIGNAL_UNITS)
    if sig["kind"] == "multisine":
        comps = sig.get("components")
        if not comps or not all(isinstance(c, list) and len(c) in (2, 3) and all(isinstance(x, NUMBER) for x in c)
                                and c[1] >= 0 for c in comps):
            fail(where, f"{prefix}.components", "expected a list of [amplitude, frequency_Hz >= 0(, phase_rad)]")
    for key in ("amplitude", "width_s", "rest_s", "hold_s", "half_s"):
        if key in sig:
            check_numbers(where, f"{prefix}.{key}", sig[key], 2, "numbers [low, high]")
            if sig[key][0] > sig[key][1]:
                fail(where, f"{prefix}.{key}", f"expected [low, high] with low <= high, got {sig[key]!r}")
            if key.endswith("_s") and not sig[key][0] > 0:
                fail(where, f"{prefix}.{key}", f"expected positive durations in s, got {sig[key]!r}")
    if "sign" in sig:
        check_choice(where, f"{prefix}.sign", sig["sign"], ("both", "positive", "negative"))
    if sig.get("seed", 0) < 0:
        fail(where, f"{prefix}.seed", f"expected an integer >= 0, got {sig['seed']!r}")


def build_signal(spec: dict, n: int, sample_time_s: float, seed: int) -> np.ndarray:
    """The excitation signal, shape (n,), in the unit of ``spec['unit']`` (offset included)."""
    rng = np.random.default_rng(spec.get("seed", seed))
    t = np.arange(n) * sample_time_s
    kind, offset = spec["kind"], float(spec.get("offset", 0.0))
    if kind == "multisine":
        return multisine(t, [tuple(c) for c in spec["components"]], offset)
    if kind == "pulses":
        base = float(spec.get("base", 0.0))
        y = pulse_train(n, sample_time_s, base, tuple(spec.get("amplitude", (0.1, 0.3))),
                        tuple(spec.get("width_s", (0.02, 0.12))), tuple(spec.get("rest_s", (0.2, 0.8))), rng)
        sign = spec.get("sign", "both")
        if sign == "positive":
            y = base + np.abs(y - base)
        elif sign == "negative":
            y = base - np.abs(y - base)
        return y + offset
    if kind == "steps":
        return offset + random_steps(n, sample_time_s, float(spec.get("low", -1.0)), float(spec.get("high", 1.0)),
                                     tuple(spec.get("hold_s", (1.0, 4.0))), rng)
    return offset + command_doublets(n, sample_time_s, 0.0, tuple(spec.get("amplitude", (1.5, 3.0))),
                                     tuple(spec.get("half_s", (0.08, 0.2))), tuple(spec.get("rest_s", (0.8, 2.5))), rng)


def sensor_gain(rig: Rig) -> float:
    """Position sensor gain in V/m (``position_sensor_V_per_m``, else 10 V over the stroke)."""
    return float(rig.params.get("position_sensor_V_per_m", 10.0 / rig.stroke_m))


def build_experiment(rig: Rig, exp: dict) -> tuple[Experiment, np.ndarray]:
    """The :class:`~pneusim.experiment.Experiment` of an ``[experiment]`` table, and the raw signal.

    Returns
    -------
    experiment : Experiment
        Signal in SI units (V open loop, m closed loop).
    raw_signal : ndarray, shape (N,)
        The signal in the scenario's own unit (what ``data.input = "signal"`` uses).
    """
    ts = float(exp.get("sample_time_s") or rig.sample_time_s)
    n = int(round(exp["duration_s"] / ts))
    if n < 50:
        raise PneusimError(f"experiment.duration_s = {exp['duration_s']} s gives {n} samples at {ts} s; "
                           "at least 50 are needed")
    spec = exp["signal"]
    raw = build_signal(spec, n, ts, int(exp.get("seed", 0)))
    if exp["loop"] == "closed":
        sig = raw / sensor_gain(rig) if spec.get("unit") == "sensor_V" else raw
        c = exp.get("controller") or {}
        kp = float(c.get("kp_V_per_m", DEFAULT_KP_V_PER_M.get(rig.name, 12.0 / rig.stroke_m)))
        ctrl = ProportionalController(kp, float(c.get("u0_V", rig.params["valve_null_V"])),
                                      float(c.get("u_min_V", rig.params["valve_min_V"])),
                                      float(c.get("u_max_V", rig.params["valve_max_V"])))
    else:
        if spec.get("unit") not in ("native", None):
            raise PneusimError(f"an open-loop signal is a valve command in V; signal unit {spec.get('unit')!r} "
                               "only applies to a closed-loop reference")
        sig, ctrl = raw, None
    experiment = Experiment(exp["loop"], ts, sig, ctrl, warmup_s=float(exp.get("warmup_s", 1.0)),
                            initial_position_m=exp.get("initial_position_m"),
                            description=f"{exp['loop']}-loop {spec['kind']} ({spec.get('note', 'scenario')})")
    return experiment, raw


def output_scale(rig: Rig, unit: str) -> float:
    """Metres to the output unit ``unit`` (:data:`OUTPUT_UNITS`): the factor, or the sensor gain in V/m."""
    return sensor_gain(rig) if unit == "sensor_V" else OUTPUT_SCALE[unit]


def output_signal(position_m: np.ndarray, rig: Rig, data: dict) -> np.ndarray:
    """The identifiers' output ``y`` (unit ``data.output_unit``, minus ``data.output_offset``)."""
    return np.asarray(position_m) * output_scale(rig, data["output_unit"]) - float(data["output_offset"])


def input_signal(valve_cmd_V: np.ndarray, raw_signal: np.ndarray, data: dict) -> np.ndarray:
    """The identifiers' input ``u``: the valve command in V or the scenario signal, minus ``data.input_offset``."""
    u = valve_cmd_V if data["input"] == "valve_cmd_V" else raw_signal
    return np.asarray(u, dtype=float) - float(data["input_offset"])
