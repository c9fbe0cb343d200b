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

from ..metrics import error_stats, fit_percent
from ..online import make_rls
from ..rig import load_rig
from ..signals import build_experiment, input_signal, output_scale, output_signal
from ..simulate import merged_effects, simulate
from . import identify as idf
from .analysis import excitation_freqs_Hz, free_run, theta_to_z, valve_velocity_gain, z_properties
from .generalisation import evaluate_conditions
from .online import simulate_online

__all__ = ["ScenarioResult", "run_scenario", "run_experiment_variant", "run_rig_variant", "end_stop_summary"]


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
        progress on the simulations (a bar on a terminal, a line every few seconds in a log).
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
    t0 = time.perf_counter()
    rec, preds, thetas = _main_run(rig, experiment, raw, effects, online, exp_spec, data, progress)
    timings["simulation_s"] = time.perf_counter() - t0
    y = output_signal(rec.position_m, rig, data)
    u = input_signal(rec.valve_cmd_V, raw, data)
    n_est = int(round(data["estimation_fraction"] * len(y)))
    scoring = _Scoring(spec, rig, effects, rec, y, u, n_est, experiment.sample_time_s,
                       output_scale(rig, data["output_unit"]), online, preds, thetas)
    rows = []
    for ident in idents:
        t1 = time.perf_counter()
        new = scoring.rows(ident)
        dt = time.perf_counter() - t1
        for r in new:
            r["wall_time_s"] = dt + (timings["simulation_s"] if ident["kind"] == "rls" else 0.0)
            r.setdefault("scored_on", "whole online run" if ident["kind"] in ("rls", "published_z")
                         else "validation half")
        rows.extend(new)
    result = ScenarioResult(spec, rows, rec, y, u, n_est, thetas=thetas, rig_name=rig.name, rig=rig,
                            output_per_m=scoring.scale, effects=effects, experiment=experiment)
    if variants:
        result.variants = [run_experiment_variant(rig, effects, exp_spec, var, progress)
                           for var in spec.get("variants", [])]
    if variants and spec.get("rig_variants"):
        t1 = time.perf_counter()
        result.rig_variants = [run_rig_variant(spec, rv, progress) for rv in spec["rig_variants"]]
        timings["rig_variants_s"] = time.perf_counter() - t1
    if spec.get("conditions"):
        t1 = time.perf_counter()
        result.generalisation = evaluate_conditions(result, progress=progress)
        timings["conditions_s"] = time.perf_counter() - t1
    result.timings_s = {**timings, "total_s": time.perf_counter() - started}
    result.timings_s["main_run_end_stops"] = end_stop_summary(rec.position_m, rig.stroke_m, experiment.sample_time_s)
    return result


def _main_run(rig, experiment, raw, effects, online: dict, exp_spec: dict, data: dict, progress: bool):
    """The scenario's run: ``(recording, predictions, thetas)``, with the online estimators inside the loop
    when there are any (their input is the valve command or the scenario's signal, ``data.input``)."""
    seed, noise = int(exp_spec["seed"]), float(exp_spec["noise_scale"])
    if not online:
        sim = simulate(rig, experiment, effects, seed=seed, noise_scale=noise, progress=progress)
        return sim.recording, {}, {}
    scale = output_scale(rig, data["output_unit"])
    y_off, u_off = float(data["output_offset"]), float(data["input_offset"])
    use_signal = data["input"] == "signal"
    res = simulate_online(rig, experiment, online, lambda p: p * scale - y_off,
                          lambda u, k: (raw[k] if use_signal else u) - u_off, effects,
                          seed=seed, noise_scale=noise, progress=progress)
    return res.recording, res.predictions, res.thetas


@dataclass
class _Scoring:
    """What the identifiers are scored on: the main run, its output ``y`` and input ``u``, the split."""

    spec: dict
    rig: object
    effects: list
    recording: object
    y: np.ndarray
    u: np.ndarray
    n_est: int
    sample_time_s: float
    scale: float
    online: dict
    preds: dict
    thetas: dict

    def rows(self, ident: dict) -> list[dict]:
        """The rows of one identifier (one per reading)."""
        kind, y, u, n_est = ident["kind"], self.y, self.u, self.n_est
        est, val = (y[:n_est], u[:n_est]), (y[n_est:], u[n_est:])
        if kind == "rls":
            return self.online_rows(ident)
        if kind == "published_z":
            return idf.score_published_z(ident, y, u)
        if kind == "published_s":
            n, ts = len(y), self.sample_time_s
            return idf.score_published_s(ident, val, ts, record_s=n * ts,
                                         band_Hz=excitation_freqs_Hz(self.spec["experiment"]["signal"], n * ts),
                                         output_per_m=self.scale)
        if kind == "physical_fit":
            data = self.spec["data"]
            model_effects = self.effects if ident.get("model_effects", "scenario") == "scenario" else []
            return idf.run_physical_fit(ident, self.recording, n_est, self.rig, model_effects,
                                        lambda p: output_signal(p, self.rig, data), val[0])
        return idf.run_blackbox(ident, est, val, self.sample_time_s)

    def online_rows(self, ident: dict) -> list[dict]:
        """An online estimator: one row per horizon, scored over the whole run; the 1-step row also runs
        the final model free (driven by the input alone)."""
        y, u = self.y, self.u
        new = []
        for h in ident["horizons"]:
            yhat = self.preds[(ident["name"], h)]
            th = self.thetas[ident["name"]][-1]
            num_z, den_z = theta_to_z(th, ident["order"])
            new.append({"identifier": ident["name"], "kind": ident["kind"], "reading": f"online, {h}-step prediction",
                        "horizon": h, "order": ident["order"], "forgetting": ident["forgetting"],
                        "engine": self.online[ident["name"]].engine,
                        "status": "ok", **error_stats(y, yhat), "_yhat": yhat,
                        "theta_final": [float(v) for v in th], **z_properties(num_z, den_z)})
            if h == 1:
                free = free_run(num_z, den_z, y, u)
                new[-1].update(free_run_fit_percent=fit_percent(y, free), _free=free)
        return new


def run_experiment_variant(rig, effects, exp_spec: dict, variant: dict, progress: bool = False) -> dict:
    """A ``[[variants]]`` run: the experiment with the variant's keys, where the piston went (and, open loop,
    the valve's velocity gain); ``{"name", "description", "recording", "summary"}``."""
    t1 = time.perf_counter()
    vexp = copy.deepcopy(exp_spec)
    vexp.update(variant.get("experiment", {}))
    vexperiment, _ = build_experiment(rig, vexp)
    vsim = simulate(rig, vexperiment, effects, seed=int(vexp["seed"]), noise_scale=float(vexp["noise_scale"]),
                    progress=progress)
    vrec = vsim.recording
    summary = end_stop_summary(vrec.position_m, rig.stroke_m, vexperiment.sample_time_s)
    summary.update(loop=vexp["loop"], wall_time_s=time.perf_counter() - t1)
    if vexp["loop"] == "open":
        summary["valve_velocity_gain"] = valve_velocity_gain(
            vrec.position_m, vrec.valve_cmd_V, vexperiment.sample_time_s, rig.params["valve_null_V"], rig.stroke_m)
    return {"name": variant["name"], "description": variant.get("description", ""), "recording": vsim.recording,
            "summary": summary}


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
