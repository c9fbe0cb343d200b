"""Write a scenario's report: report.md, report.html (figures embedded), metrics.json, recordings, PNGs.

The report is built once as a list of blocks (heading, paragraph, list, table,
figure) and rendered twice, to Markdown and to self-contained HTML
(:mod:`pneusim.plotting.page`).  The paper-specific tables (``scenario.layout``)
live in :mod:`.tables`.
"""

from __future__ import annotations

import csv
import shlex
from pathlib import Path

import numpy as np

from ..outputs import atomic_path, write_json_atomic
from ..plotting import write_page
from ..recording import write_recording
from .identify import clean_row
from .runner import ScenarioResult
from .figures import make_figures, slug
from .generalisation import clean_generalisation, generalisation_blocks
from .rigcompare import rig_variant_blocks
from .tables import layout_blocks, rows_table, unit_label

__all__ = ["write_report", "metrics_dict"]


def metrics_dict(result: ScenarioResult, files: dict) -> dict:
    """The JSON written as metrics.json (strict JSON: NaN as null)."""
    spec, rec = result.spec, result.recording
    return {"format": "pneusim-scenario-metrics/1", "scenario": spec["scenario"]["name"], "rig": result.rig_name,
            "rig_overrides": spec["rig"]["overrides"], "effects": spec["rig"]["effects"],
            "experiment": {k: v for k, v in spec["experiment"].items()},
            "data": spec["data"], "n_samples": int(rec.n_samples), "sample_time_s": rec.sample_time_s,
            "n_estimation": int(result.n_estimation), "rows": [clean_row(r) for r in result.rows],
            "variants": [{"name": v["name"], "description": v["description"], **v["summary"]}
                         for v in result.variants],
            "rig_variants": [{**{k: v for k, v in rv.items() if k != "rows"},
                              "rows": [clean_row(r) for r in rv["rows"]]} for rv in result.rig_variants],
            "generalisation": clean_generalisation(result.generalisation),
            "timings_s": result.timings_s, "files": files}


def write_predictions(result: ScenarioResult, path) -> list[str]:
    """``predictions.csv``: time, the identifiers' y and u, and one column per scored row with its
    model output (``IDENTIFIER | READING``; empty where the row is not scored).  Returns the column names."""
    n = len(result.y)
    cols = {"time_s": result.recording.time_s, "y": result.y, "u": result.u}
    for r in result.rows:
        yhat = r.get("_yhat")
        if yhat is None:
            continue
        full = np.full(n, np.nan)
        full[n - len(yhat):] = yhat
        cols[f"{r['identifier']} | {r.get('reading', '')}"] = full
    names = list(cols)
    data = np.column_stack([np.asarray(cols[c], float) for c in names])
    with atomic_path(path) as tmp, open(tmp, "x", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(names)
        for row in data:
            writer.writerow(["" if not np.isfinite(v) else repr(float(v)) for v in row])
    return names


def _variants_blocks(result: ScenarioResult) -> list:
    """The main run and each variant: where the piston went (and, open loop, its velocity gain)."""
    if not result.variants:
        return []
    main = result.timings_s["main_run_end_stops"]
    runs = [("main run", result.spec["experiment"]["loop"], main)] + [(v["name"], v["summary"]["loop"], v["summary"])
                                                                    for v in result.variants]
    body = [[name, loop, f"{s['position_min_m'] * 1e3:.1f}", f"{s['position_max_m'] * 1e3:.1f}",
             f"{s['stroke_m'] * 1e3:g}", f"{100 * s['fraction_at_end_stop']:.1f}",
             "never" if s["first_end_stop_s"] is None else f"{s['first_end_stop_s']:g}"] for name, loop, s in runs]
    blocks = [("h", (2, "Variants: where the piston goes")),
              ("p", "Each variant is the main experiment with some keys changed, simulated on the same rig. "
                    "'At an end stop' counts the samples within 1 mm of either end of the stroke.")]
    blocks.append(("table", (["run", "loop", "position min (mm)", "position max (mm)", "stroke (mm)",
                              "time at an end stop (%)", "first end-stop contact (s)"], body)))
    items = [f"{v['name']}: {v['description']}" for v in result.variants]
    for v in result.variants:
        g = v["summary"].get("valve_velocity_gain")
        if g:
            items.append(f"{v['name']}: piston velocity = {1e3 * g['gain_m_per_s_per_V']:.3g} mm/s per V of valve "
                         f"command from the null (least squares over {g['n']} samples away from the end stops, "
                         f"R^2 = {g['r2']:.2f}): the rig integrates its valve command.")
    blocks.append(("ul", items))
    return blocks


def write_report(result: ScenarioResult, out_dir, scenario_path: str = "SCENARIO.toml", overrides=()) -> dict:
    """Write everything into ``out_dir`` (created); returns the metrics dict written as metrics.json.

    ``overrides`` are the ``--set KEY=VALUE`` items the run was made with (shown in the report).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spec = result.spec
    files = {"recording": "recording.csv", "predictions": "predictions.csv"}
    write_recording(result.recording, out / "recording.csv")
    write_predictions(result, out / "predictions.csv")
    for v in result.variants:
        name = f"variant-{slug(v['name'])}.csv"
        write_recording(v["recording"], out / name)
        files[f"variant:{v['name']}"] = name
    figs = make_figures(result, out)
    files["figures"] = [f for f, _ in figs]
    metrics = metrics_dict(result, files)
    metrics["overrides"] = list(overrides)
    write_json_atomic(out / "metrics.json", metrics, indent=1, allow_nan=False)
    sc, exp, data = spec["scenario"], spec["experiment"], spec["data"]
    title = sc["title"] or sc["name"]
    blocks = [("h", (1, title))]
    if sc["description"].strip():
        blocks.append(("p", " ".join(sc["description"].split())))
    if overrides:
        blocks.append(("p", "Run with changed keys: " + ", ".join(overrides) + " (numbers below are for this run)."))
    if sc["notes"]:
        blocks += [("h", (2, "Readings and choices")), ("ul", list(sc["notes"]))]
    rec = result.recording
    unit = unit_label(data["output_unit"])
    u_text = ("the valve command in V" if data["input"] == "valve_cmd_V"
              else f"the scenario signal ({exp['signal'].get('unit', 'native')})")
    y_text = {"sensor_V": "the position sensor's voltage"}.get(data["output_unit"], f"the position in {unit}")
    blocks += [("h", (2, "Setup")), ("ul", [
        f"Rig: {result.rig_name}; parameter overrides: {spec['rig']['overrides'] or 'none'}; effects: "
        f"{', '.join(spec['rig']['effects']) or 'none'}.",
        f"Experiment: {exp['loop']} loop, {exp['signal']['kind']} signal, {rec.n_samples} samples at "
        f"{rec.sample_time_s * 1e3:g} ms ({rec.n_samples * rec.sample_time_s:g} s), seed {exp['seed']}, "
        f"sensor noise x{exp['noise_scale']}.",
        f"Identification data: y = {y_text}" + (f" minus {data['output_offset']:g} {unit}" if data["output_offset"]
                                                 else "")
        + f"; u = {u_text}" + (f" minus {data['input_offset']:g}" if data["input_offset"] else "")
        + f". Estimation on the first {result.n_estimation} samples, validation on the remaining "
          f"{rec.n_samples - result.n_estimation}.",
        f"Run time: simulation {result.timings_s['simulation_s']:.1f} s, total {result.timings_s['total_s']:.1f} s.",
    ])]
    blocks += layout_blocks(result)
    blocks += rig_variant_blocks(result)
    gen_blocks = generalisation_blocks(result, out)
    blocks += [b for b in gen_blocks if b[0] != "fig"]
    blocks += [("h", (2, "All rows")),
               ("p", "Every identifier and reading with the metrics listed in the scenario; metrics.json holds "
                     "all of them (fit %, mse = square error, rmse, min/max/std of actual, predicted and error), "
                     "predictions.csv each model's output beside y and u."),
               ("table", rows_table(result.rows, spec["metrics"]["report"]))]
    blocks += _variants_blocks(result)
    blocks.append(("h", (2, "Figures")))
    blocks += [("fig", f) for f in figs]
    blocks += [b for b in gen_blocks if b[0] == "fig"]
    sets = "".join(f" --set {shlex.quote(o)}" for o in overrides)
    blocks += [("h", (2, "Reproduce")), ("code", f"pneusim run {scenario_path}{sets} --out {out_dir}")]
    write_page(blocks, out, title, markdown="report.md", html_name="report.html")
    return metrics
