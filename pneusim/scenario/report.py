"""Write a scenario's report: report.md, report.html (figures embedded), metrics.json, recordings, PNGs.

The report is built once as a list of blocks (heading, paragraph, list, table,
figure) and rendered twice, to Markdown and to self-contained HTML.  The
paper-specific tables (``scenario.layout``) live in :mod:`.tables`.
"""

from __future__ import annotations

import base64
import html
import json
import re
from pathlib import Path

import numpy as np

from ..recording import write_recording
from .identify import clean_row
from .runner import ScenarioResult
from .tables import layout_blocks, rows_table

__all__ = ["write_report", "metrics_dict"]


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


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
            "timings_s": result.timings_s, "files": files}


def _figure_prediction(path, t, y, yhat, title, unit):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 1, sharex=True, figsize=(9, 4.6), gridspec_kw={"height_ratios": [2, 1]})
    ax[0].plot(t, y, lw=0.9, label="actual output")
    ax[0].plot(t, yhat, lw=0.8, ls="--", label="predicted output")
    ax[0].set_ylabel(f"output ({unit})")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[1].plot(t, y - yhat, lw=0.7, color="C3")
    ax[1].set_ylabel(f"error ({unit})")
    ax[1].set_xlabel("time (s)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _figure_models(path, t, y, rows, title, unit):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(t, y, lw=1.2, color="k", label="measured (simulated rig)")
    for r in rows:
        fit = r.get("fit_percent")
        label = f"{r['identifier']} {r.get('reading', '')}".strip() + (f": {fit:.1f} %" if fit == fit else "")
        ax.plot(t, r["_yhat"], lw=0.8, label=label)
    lo, hi = np.nanmin(y), np.nanmax(y)
    span = hi - lo
    ax.set_ylim(lo - 0.6 * span, hi + 0.6 * span)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"output ({unit})")
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _figures(result: ScenarioResult, out: Path) -> list[tuple[str, str]]:
    """Draw the PNG figures; returns ``[(file name, caption)]``."""
    from ..plots import plot_recording

    figs = []
    rec, unit = result.recording, result.spec["data"]["output_unit"]
    plot_recording(rec, out / "recording.png", title=f"{result.spec['scenario']['name']}: simulated run")
    figs.append(("recording.png", "The simulated run: position and reference, valve command, chamber pressures."))
    t = rec.time_s
    n_est = result.n_estimation
    for r in result.rows:
        if r.get("kind") == "rls" and "_yhat" in r:
            name = f"rls-{_slug(r['identifier'])}-h{r['horizon']}.png"
            _figure_prediction(out / name, t, result.y, r["_yhat"],
                               f"{r['identifier']}, {r['horizon']}-step prediction: actual, predicted, error", unit)
            figs.append((name, f"On-line actual output, {r['identifier']} at {r['horizon']}-step prediction, "
                               "and the error versus time (the paper's figures 5-9)."))
    pub_z = [r for r in result.rows if r.get("kind") == "published_z" and "_yhat" in r]
    if pub_z:
        _figure_models(out / "published-z.png", t, result.y, pub_z,
                       "Published discrete models (eqs. 9-11), one-step prediction on our data", unit)
        figs.append(("published-z.png", "The paper's published models predicting our simulated data one step ahead."))
    val_rows = [r for r in result.rows if "_yhat" in r and r.get("kind") not in ("rls", "published_z")
                and len(r["_yhat"]) == len(t) - n_est]
    blackbox = [r for r in val_rows if r["kind"] != "published_s"]
    if blackbox:
        _figure_models(out / "validation.png", t[n_est:], result.y[n_est:], blackbox,
                       "Validation half: measured and simulated model outputs", unit)
        figs.append(("validation.png", "Validation data and the simulated output of each identified model."))
    pub_s = [r for r in val_rows if r["kind"] == "published_s"]
    if pub_s:
        _figure_models(out / "published-s.png", t[n_est:], result.y[n_est:], pub_s,
                       "Published continuous model (eq. 4) under each time-unit reading", unit)
        figs.append(("published-s.png", "Equation 4 simulated on the validation half under each time-unit reading "
                                        "(axes clipped around the measured output)."))
    for v in result.variants:
        name = f"variant-{_slug(v['name'])}.png"
        plot_recording(v["recording"], out / name, title=f"variant: {v['name']}")
        figs.append((name, f"Variant '{v['name']}': {v['description']}"))
    return figs


def _render_md(blocks) -> str:
    out = []
    for kind, payload in blocks:
        if kind == "h":
            level, text = payload
            out.append("#" * level + " " + text)
        elif kind == "p":
            out.append(payload)
        elif kind == "ul":
            out.append("\n".join(f"* {item}" for item in payload))
        elif kind == "table":
            header, rows = payload
            out.append("| " + " | ".join(header) + " |\n|" + "---|" * len(header) + "\n"
                       + "\n".join("| " + " | ".join(str(c) for c in row) + " |" for row in rows))
        elif kind == "fig":
            name, caption = payload
            out.append(f"![{caption}]({name})\n\n*{caption}*")
        elif kind == "code":
            out.append(f"```\n{payload}\n```")
    return "\n\n".join(out) + "\n"


def _render_html(blocks, title: str, out: Path) -> str:
    body = []
    for kind, payload in blocks:
        if kind == "h":
            level, text = payload
            body.append(f"<h{level}>{html.escape(text)}</h{level}>")
        elif kind == "p":
            body.append(f"<p>{html.escape(payload)}</p>")
        elif kind == "ul":
            body.append("<ul>" + "".join(f"<li>{html.escape(i)}</li>" for i in payload) + "</ul>")
        elif kind == "table":
            header, rows = payload
            body.append("<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>"
                        + "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>"
                                  for row in rows) + "</table>")
        elif kind == "fig":
            name, caption = payload
            data = base64.b64encode((out / name).read_bytes()).decode("ascii")
            body.append(f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
                        f"<figcaption>{html.escape(caption)}</figcaption></figure>")
        elif kind == "code":
            body.append(f"<pre>{html.escape(payload)}</pre>")
    style = ("body{font-family:sans-serif;max-width:60em;margin:2em auto;line-height:1.4}"
             "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #999;padding:2px 6px;"
             "font-size:90%}img{max-width:100%}figcaption{font-style:italic;font-size:90%}")
    return (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{style}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


def write_report(result: ScenarioResult, out_dir, scenario_path: str = "SCENARIO.toml") -> dict:
    """Write everything into ``out_dir`` (created); returns the metrics dict written as metrics.json."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spec = result.spec
    files = {"recording": "recording.csv"}
    write_recording(result.recording, out / "recording.csv")
    for v in result.variants:
        name = f"variant-{_slug(v['name'])}.csv"
        write_recording(v["recording"], out / name)
        files[f"variant:{v['name']}"] = name
    figs = _figures(result, out)
    files["figures"] = [f for f, _ in figs]
    metrics = metrics_dict(result, files)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1, allow_nan=False), encoding="utf-8")
    sc, exp = spec["scenario"], spec["experiment"]
    title = sc["title"] or sc["name"]
    blocks = [("h", (1, title))]
    if sc["description"].strip():
        blocks.append(("p", " ".join(sc["description"].split())))
    if sc["notes"]:
        blocks += [("h", (2, "Readings and choices")), ("ul", list(sc["notes"]))]
    rec = result.recording
    blocks += [("h", (2, "Setup")), ("ul", [
        f"Rig: {result.rig_name}; overrides: {spec['rig']['overrides'] or 'none'}; effects: "
        f"{', '.join(spec['rig']['effects']) or 'none'}.",
        f"Experiment: {exp['loop']} loop, {exp['signal']['kind']} signal, {rec.n_samples} samples at "
        f"{rec.sample_time_s * 1e3:g} ms ({rec.n_samples * rec.sample_time_s:g} s), seed {exp['seed']}, "
        f"sensor noise x{exp['noise_scale']}.",
        f"Identification data: y = position in {spec['data']['output_unit']} minus {spec['data']['output_offset']}, "
        f"u = {spec['data']['input']} minus {spec['data']['input_offset']}; estimation on the first "
        f"{result.n_estimation} samples, validation on the remaining {rec.n_samples - result.n_estimation}.",
        f"Run time: simulation {result.timings_s['simulation_s']:.1f} s, total {result.timings_s['total_s']:.1f} s.",
    ])]
    blocks += layout_blocks(result)
    blocks += [("h", (2, "All rows")), ("table", rows_table(result.rows, spec["metrics"]["report"]))]
    if result.variants:
        blocks.append(("h", (2, "Variants")))
        blocks.append(("table", (["variant", "loop", "position min (mm)", "position max (mm)",
                                  "time at an end stop (%)", "first end-stop contact (s)"],
                                 [[v["name"], v["summary"]["loop"], f"{v['summary']['position_min_m'] * 1e3:.1f}",
                                   f"{v['summary']['position_max_m'] * 1e3:.1f}",
                                   f"{100 * v['summary']['fraction_at_end_stop']:.1f}",
                                   v["summary"]["first_end_stop_s"]] for v in result.variants])))
    blocks.append(("h", (2, "Figures")))
    blocks += [("fig", f) for f in figs]
    blocks += [("h", (2, "Reproduce")), ("code", f"pneusim run {scenario_path} --out {out_dir}")]
    (out / "report.md").write_text(_render_md(blocks), encoding="utf-8")
    (out / "report.html").write_text(_render_html(blocks, title, out), encoding="utf-8")
    return metrics
