"""Run a validated scenario: simulate, identify, score; return a result (no files written).

:func:`run_scenario` is pure apart from the optional progress bar: a sweep calls
it in worker processes, ``pneusim run`` calls it and then
:func:`pneusim.scenario.report.write_report`.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field

import numpy as np

from ..model import parse_effect_text
from ..rig import load_rig
from ..simulate import simulate
from . import identify as idf
from .analysis import excitation_freqs_Hz, free_run, theta_to_z, valve_velocity_gain, z_properties
from .online import make_rls, simulate_online
from .signals import build_experiment, input_signal, output_signal, sensor_gain

__all__ = ["ScenarioResult", "run_scenario", "end_stop_summary"]


@dataclass
class ScenarioResult:
    """Everything a report needs.

    Attributes
    ----------
    spec : dict
        The validated scenario.
    rows : list of dict
        One per identifier and reading (metrics; private ``_yhat`` arrays kept for figures).
    recording : Recording
        The main simulated run.
    y, u : ndarray, shape (N,)
        The identifiers' output and input (units of ``spec['data']``).
    n_estimation : int
        Samples used for estimation (the rest validate).
    variants : list of dict
        ``{"name", "description", "recording", "summary"}`` for each extra run.
    timings_s : dict
    """

    spec: dict
    rows: list
    recording: object
    y: np.ndarray
    u: np.ndarray
    n_estimation: int
    thetas: dict = field(default_factory=dict)
    variants: list = field(default_factory=list)
    timings_s: dict = field(default_factory=dict)
    rig_name: str = ""
    rig: object = None
    output_per_m: float = 1.0
    #: ``[{"name", "rig", "effects", "description", "rows", "rig_name"}]``: the scenario re-run on other rigs
    rig_variants: list = field(default_factory=list)
    #: what :func:`pneusim.scenario.generalisation.evaluate_conditions` returns, or ``None``
    generalisation: dict | None = None
    effects: list = field(default_factory=list)
    experiment: object = None


def merged_effects(rig, texts) -> list:
    """The rig's own effects (a rig variant's ``[effects]``) plus the scenario's; a scenario effect replaces
    the rig's effect of the same name."""
    own = [parse_effect_text(t) for t in texts]
    names = {e.name for e in own}
    return [e for e in (parse_effect_text(t) for t in getattr(rig, "effects", ())) if e.name not in names] + own


def end_stop_summary(position_m: np.ndarray, stroke_m: float, sample_time_s: float, margin_m: float = 1e-3) -> dict:
    """Where the piston went: range, fraction of samples within ``margin_m`` of an end stop, first contact [s]."""
    at_stop = (position_m <= margin_m) | (position_m >= stroke_m - margin_m)
    first = int(np.argmax(at_stop)) if at_stop.any() else None
    return {"position_min_m": float(position_m.min()), "position_max_m": float(position_m.max()),
            "fraction_at_end_stop": float(at_stop.mean()),
            "first_end_stop_s": None if first is None else first * sample_time_s,
            "stroke_m": stroke_m}


def run_scenario(spec: dict, progress: bool = False, variants: bool = True) -> ScenarioResult:
    """Simulate the scenario's experiment with its online identifiers in the loop, then score all identifiers.

    Parameters
    ----------
    spec : dict
        A scenario validated by :func:`~pneusim.scenario.schema.validate_scenario`.
    progress : bool
        tqdm progress bars on the simulations.
    variants : bool
        Also run the ``[[variants]]`` (extra experiments reported beside the main one).
    """
    timings = {}
    started = time.perf_counter()
    rig = load_rig(spec["rig"]["name"])
    if spec["rig"]["overrides"]:
        rig = rig.with_params(spec["rig"]["overrides"])
    effects = merged_effects(rig, spec["rig"]["effects"])
    exp_spec, data = spec["experiment"], spec["data"]
    experiment, raw = build_experiment(rig, exp_spec)
    if experiment.sample_time_s != rig.sample_time_s:
        rig = rig.with_params({"sample_time_s": experiment.sample_time_s})
    idents = [i for i in spec["identifiers"] if i.get("enabled", True)]
    online = {i["name"]: make_rls(i["order"], i["forgetting"], i["initial_covariance"], i["horizons"],
                                  i.get("engine", "auto"))
              for i in idents if i["kind"] == "rls"}
    seed, noise = int(exp_spec["seed"]), float(exp_spec["noise_scale"])
    t0 = time.perf_counter()
    gain = sensor_gain(rig)
    scale = {"m": 1.0, "cm": 100.0, "mm": 1000.0, "sensor_V": gain}[data["output_unit"]]
    y_off, u_off = float(data["output_offset"]), float(data["input_offset"])
    if online:
        use_signal = data["input"] == "signal"
        res = simulate_online(rig, experiment, online, lambda p: p * scale - y_off,
                              lambda u, k: (raw[k] if use_signal else u) - u_off, effects,
                              seed=seed, noise_scale=noise, progress=progress)
        rec, preds, thetas = res.recording, res.predictions, res.thetas
    else:
        sim = simulate(rig, experiment, effects, seed=seed, noise_scale=noise, progress=progress)
        rec, preds, thetas = sim.recording, {}, {}
    timings["simulation_s"] = time.perf_counter() - t0
    y = output_signal(rec.position_m, rig, data)
    u = input_signal(rec.valve_cmd_V, raw, data)
    n = len(y)
    n_est = int(round(data["estimation_fraction"] * n))
    ts = experiment.sample_time_s
    est, val = (y[:n_est], u[:n_est]), (y[n_est:], u[n_est:])
    rows = []
    for ident in idents:
        t1 = time.perf_counter()
        kind = ident["kind"]
        if kind == "rls":
            new = []
            for h in ident["horizons"]:
                yhat = preds[(ident["name"], h)]
                th = thetas[ident["name"]][-1]
                num_z, den_z = theta_to_z(th, ident["order"])
                new.append({"identifier": ident["name"], "kind": kind, "reading": f"online, {h}-step prediction",
                            "horizon": h, "order": ident["order"], "forgetting": ident["forgetting"],
                            "engine": online[ident["name"]].engine,
                            "status": "ok", **idf.error_stats(y, yhat), "_yhat": yhat,
                            "theta_final": [float(v) for v in th], **z_properties(num_z, den_z)})
                if h == 1:
                    free = free_run(num_z, den_z, y, u)
                    new[-1].update(free_run_fit_percent=idf.fit_percent(y, free), _free=free)
        elif kind == "published_z":
            new = idf.score_published_z(ident, y, u)
        elif kind == "published_s":
            new = idf.score_published_s(ident, val, ts, record_s=n * ts,
                                        band_Hz=excitation_freqs_Hz(exp_spec["signal"], n * ts),
                                        output_per_m=scale)
        elif kind == "physical_fit":
            model_effects = effects if ident.get("model_effects", "scenario") == "scenario" else []
            new = idf.run_physical_fit(ident, rec, n_est, rig, model_effects,
                                       lambda p: output_signal(p, rig, data), val[0])
        else:
            new = idf.run_blackbox(ident, est, val, ts)
        dt = time.perf_counter() - t1
        for r in new:
            r["wall_time_s"] = dt + (timings["simulation_s"] if kind == "rls" else 0.0)
            r.setdefault("scored_on", "whole online run" if kind in ("rls", "published_z") else "validation half")
        rows.extend(new)
    result = ScenarioResult(spec, rows, rec, y, u, n_est, thetas=thetas, rig_name=rig.name, rig=rig,
                            output_per_m=scale, effects=effects, experiment=experiment)
    if variants:
        for var in spec.get("variants", []):
            t1 = time.perf_counter()
            vexp = copy.deepcopy(exp_spec)
            vexp.update(var.get("experiment", {}))
            vexperiment, _ = build_experiment(rig, vexp)
            vsim = simulate(rig, vexperiment, effects, seed=int(vexp["seed"]), noise_scale=float(vexp["noise_scale"]),
                            progress=progress)
            vrec = vsim.recording
            summary = end_stop_summary(vrec.position_m, rig.stroke_m, vexperiment.sample_time_s)
            summary.update(loop=vexp["loop"], wall_time_s=time.perf_counter() - t1)
            if vexp["loop"] == "open":
                summary["valve_velocity_gain"] = valve_velocity_gain(
                    vrec.position_m, vrec.valve_cmd_V, vexperiment.sample_time_s, rig.params["valve_null_V"],
                    rig.stroke_m)
            result.variants.append({"name": var["name"], "description": var.get("description", ""),
                                    "recording": vsim.recording, "summary": summary})
    if variants and spec.get("rig_variants"):
        t1 = time.perf_counter()
        result.rig_variants = [run_rig_variant(spec, rv, progress) for rv in spec["rig_variants"]]
        timings["rig_variants_s"] = time.perf_counter() - t1
    if spec.get("conditions"):
        from .generalisation import evaluate_conditions

        t1 = time.perf_counter()
        result.generalisation = evaluate_conditions(result, progress=progress)
        timings["conditions_s"] = time.perf_counter() - t1
    result.timings_s = {**timings, "total_s": time.perf_counter() - started}
    result.timings_s["main_run_end_stops"] = end_stop_summary(rec.position_m, rig.stroke_m, ts)
    return result


def run_rig_variant(spec: dict, variant: dict, progress: bool = False) -> dict:
    """The scenario re-run on ``variant['rig']`` (with its effects): same experiment, seed and identifiers;
    the physical fit only if ``variant['physical']`` (it is the expensive row).  Returns the rows."""
    sub = copy.deepcopy(spec)
    sub["rig"]["name"] = variant["rig"]
    sub["rig"]["effects"] = list(variant.get("effects", []))
    sub["rig_variants"], sub["variants"], sub["conditions"] = [], [], []
    for ident in sub["identifiers"]:
        if ident["kind"] == "physical_fit" and not variant.get("physical", False):
            ident["enabled"] = False
    res = run_scenario(sub, progress=progress, variants=False)
    return {"name": variant["name"], "rig": variant["rig"], "rig_name": res.rig_name,
            "effects": [e.to_text() for e in res.effects], "description": variant.get("description", ""),
            "rows": res.rows, "total_s": res.timings_s["total_s"]}
