"""The report folder of a diagnosis: ``index.html`` (open this one), ``report.md``, plots, ``diagnosis.json``.

Plots (PNG):

* ``fit.png`` -- measured position (and pressures) against the fitted nominal model and the improved
  model (all findings switched on), the mismatch episodes shaded, the validation part marked;
* ``zoom.png`` -- the same three curves over the strongest mismatch episode, each above its residual (measured minus
  model, mm or kPa), where the difference can be seen;
* ``residuals.png`` -- residuals before (nominal) and after (improved) over time, in units of the
  sensor noise, with the mismatch windows shaded;
* ``evidence-N-EFFECT.png`` -- the evidence of each finding, before and after modelling it (residual
  against direction, pressure difference, position, lag, or the command-velocity map).
"""

from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np

from ..outputs import savefig_atomic, write_json_atomic, write_text_atomic
from .evidence import plot_evidence, pyplot as _plt
from .locate import named_states
from .refits import noise_levels
from .result import DiagnosisResult
from .rules import SETS_SHOWN

__all__ = ["write_report"]


def _shade(ax, result, signal=None):
    """Shade the mismatch episodes on ``signal`` (all where None)."""
    for w in result.episodes or result.mismatch:
        if signal is None or w.signal == signal or signal in w.also_in:
            ax.axvspan(w.t_start_s, w.t_end_s, color="C3", alpha=0.12, lw=0)


def plot_fit(result: DiagnosisResult, path) -> Path:
    plt = _plt()
    rec = result.nominal_fit.recording
    t = rec.time_s
    nom, fin = named_states(result.nominal_fit), named_states(result.final_fit)
    signals = _signals(rec)
    fig, axes = plt.subplots(len(signals), 1, sharex=True, figsize=(11, 3.0 * len(signals)), squeeze=False)
    split = result.validation["t_start_s"]
    improved = result.findings and result.final_fit is not result.nominal_fit
    for ax, (name, y, scale, label, *_) in zip(axes[:, 0], signals):
        ax.plot(t, y * scale, lw=0.8, color="0.2", label="measured")
        ax.plot(t, nom[name] * scale, lw=0.8, color="C0", label=f"nominal ({result.nominal['fit_percent']:.1f} %)")
        if improved:
            ax.plot(t, fin[name] * scale, lw=0.8, color="C2", ls="--",
                    label=f"with {' + '.join(result.effects)} ({result.final_fit_percent:.1f} %)")
        _shade(ax, result, name)
        ax.axvline(split, color="0.4", ls=":", lw=1)
        ax.set_ylabel(label)
    axes[0, 0].set_title(f"{result.recording}: measured vs models (validation fit in brackets; validation from "
                         f"{split:.1f} s, mismatch episodes shaded)", fontsize=9)
    axes[0, 0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)


def _signals(rec) -> list:
    """``[(name, measured, scale, label, residual scale, residual unit)]`` of the measured signals, in plotting units:
    a position in mm, a pressure in bar, and a pressure's residual in kPa."""
    out = [("position_m", rec.position_m, 1e3, "position (mm)", 1e3, "mm")]
    if rec.has_pressures:
        out += [("pressure_a_Pa", rec.pressure_a_Pa, 1e-5, "p_A (bar abs)", 1e-3, "kPa"),
                ("pressure_b_Pa", rec.pressure_b_Pa, 1e-5, "p_B (bar abs)", 1e-3, "kPa")]
    return out


def strongest_episode(result: DiagnosisResult):
    """The mismatch episode with the largest residual (None without one)."""
    spans = result.episodes or result.mismatch
    return max(spans, key=lambda w: w.score) if spans else None


def plot_zoom(result: DiagnosisResult, path) -> Path:
    """Measured, nominal and with-findings curves over the strongest mismatch episode (with a margin of half its
    length, at least 0.5 s, each side), each signal above its residual (measured minus model, in the signal's unit):
    a mismatch of a fraction of a millimetre on a stroke of hundreds shows in the residual, not in the curves."""
    plt = _plt()
    rec = result.nominal_fit.recording
    t = rec.time_s
    nom, fin = named_states(result.nominal_fit), named_states(result.final_fit)
    w = strongest_episode(result)
    if w is None:
        lo, hi = float(t[0]), float(t[-1])
    else:
        margin = max(0.5, 0.5 * (w.t_end_s - w.t_start_s))
        lo, hi = max(float(t[0]), w.t_start_s - margin), min(float(t[-1]), w.t_end_s + margin)
    m = (t >= lo) & (t <= hi)
    signals = _signals(rec)
    fig, axes = plt.subplots(2 * len(signals), 1, sharex=True, figsize=(9, 3.9 * len(signals)), squeeze=False,
                             gridspec_kw={"height_ratios": [1.6, 1.0] * len(signals)})
    improved = result.findings and result.final_fit is not result.nominal_fit
    with_label = f"with {' + '.join(result.effects)}"
    for k, (name, y, scale, label, r_scale, r_unit) in enumerate(signals):
        ax, ax_r = axes[2 * k, 0], axes[2 * k + 1, 0]
        ax.plot(t[m], y[m] * scale, lw=1.0, color="0.2", label="measured")
        ax.plot(t[m], nom[name][m] * scale, lw=1.0, color="C0", label="nominal")
        ax_r.plot(t[m], (y[m] - nom[name][m]) * r_scale, lw=0.8, color="C0", label="nominal")
        if improved:
            ax.plot(t[m], fin[name][m] * scale, lw=1.0, color="C2", ls="--", label=with_label)
            ax_r.plot(t[m], (y[m] - fin[name][m]) * r_scale, lw=0.8, color="C2", label=with_label)
        ax_r.axhline(0, color="0.5", lw=0.5)
        for a in (ax, ax_r):
            if w is not None:
                a.axvspan(w.t_start_s, w.t_end_s, color="C3", alpha=0.10, lw=0)
        ax.set_ylabel(label)
        ax_r.set_ylabel(f"measured - model\n({r_unit})")
    where = (f"strongest mismatch episode {w.t_start_s:.2f}-{w.t_end_s:.2f} s on {w.signal} ({w.condition})"
             if w is not None else "no mismatch episode: the whole recording")
    fig.suptitle(f"{result.recording}: {where}", fontsize=9)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[1, 0].legend(loc="best", fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_residuals(result: DiagnosisResult, path, noise: dict) -> Path:
    plt = _plt()
    rec = result.nominal_fit.recording
    t = rec.time_s
    nom, fin = named_states(result.nominal_fit), named_states(result.final_fit)
    names = ["position_m"] + (["pressure_a_Pa", "pressure_b_Pa"] if rec.has_pressures else [])
    fig, axes = plt.subplots(len(names), 1, sharex=True, figsize=(11, 2.4 * len(names)), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        y = getattr(rec, name)
        s = noise[name]
        ax.plot(t, (y - nom[name]) / s, lw=0.6, color="C0", label="before (nominal)")
        if result.findings:
            ax.plot(t, (y - fin[name]) / s, lw=0.6, color="C2", label="after (with findings)")
        ax.axhline(0, color="0.5", lw=0.5)
        for k in (-3, 3):
            ax.axhline(k, color="0.6", lw=0.5, ls=":")
        _shade(ax, result, name)
        ax.axvline(result.validation["t_start_s"], color="0.4", ls=":", lw=1)
        ax.set_ylabel(f"{name}\nresidual / noise (-)")
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[0, 0].set_title("residuals in units of the sensor noise (dotted: +-3); shaded: mismatch beyond noise",
                         fontsize=9)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)


def _value(v):
    if isinstance(v, str):
        return v
    return f"{v:.4g}" if v is not None and math.isfinite(v) else "n/a"


def _verdict_lines(result: DiagnosisResult) -> list:
    """The verdict: the findings most important first, ``other`` and where, an incomplete search, and the table of
    validation fits with the findings."""
    lines = []
    named = [f for f in result.findings if f.effect != "other"]
    other = next((f for f in result.findings if f.effect == "other"), None)
    if not result.findings:
        verdict, because = result.no_findings
        lines.append(f"**{verdict[0].upper()}{verdict[1:]}**: {because}.")
    if named:
        lines.append("**Physics left out**, most important first: " + ", ".join(f"`{f.effect}`" for f in named) + ".")
    if other is not None:
        where = "; ".join(f"{w.t_start_s:.1f}-{w.t_end_s:.1f} s on {w.signal} ({w.condition})" for w in other.mismatch)
        lines += ["", f"**Something not in the vocabulary**, here: {where or 'see the residuals'}. "
                      "No vocabulary effect explains it (see the closest candidates below)."]
    if result.status != "complete":
        lines += ["", f"**Incomplete**: {result.status}; the findings are those made before it."]
    if result.search == "one effect first, then several":
        lines += ["", "The first findings left the model above noise: the search went on for more effects on top "
                      "of them."]
    joint = result.search == "several effects, found jointly"
    if joint:
        lines += ["", "No effect alone explained the window where the mismatch is largest: sets of effects were "
                      "fitted together there, the best set fitted whole, and each of its effects tested with the "
                      "others present."]
    lines += ["", "| model | validation fit of the position (%) |", "|---|---|",
              f"| nominal (fitted) | {result.nominal['fit_percent']:.2f} |"]
    if joint and len(named) >= 2:
        lines.append(f"| nominal + {' + '.join(f.effect for f in named)} | {result.final_fit_percent:.2f} |")
        lines += [f"| ... without `{f.effect}` | {f.fit_percent - f.improvement_points:.2f} "
                  f"({-f.improvement_points:+.2f}) |" for f in named]
    else:
        acc = []
        for f in result.findings:
            acc.append(f.effect)
            lines.append(f"| nominal + {' + '.join(acc)} | {f.fit_percent:.2f} (+{f.improvement_points:.2f}) |")
    return lines


def _markdown(result: DiagnosisResult, evidence_files) -> str:
    d = result.to_dict()
    lines = [f"# Mismatch diagnosis of {result.recording}", "",
             f"Rig `{result.rig}`; validation window {d['validation']['t_start_s']:.2f}-{d['validation']['t_end_s']:.2f} s "
             "(never used for fitting).", "",
             "## Verdict", ""]
    lines += _verdict_lines(result)
    lines += ["", "![measured vs nominal vs improved](fit.png)", "",
              "![the strongest mismatch episode, zoomed](zoom.png)", "",
              "![residuals before and after](residuals.png)", ""]
    for k, f in enumerate(result.findings):
        lines += [f"## Finding {k + 1}: `{f.effect}`", "", f"Evidence: {f.evidence}", ""]
        if f.effect == "other":
            lines += _other_lines(f)
            continue
        lines += ["| parameter | estimate | standard error |", "|---|---|---|"]
        for name, v in f.parameters.items():
            lines.append(f"| `{name}` | {_value(v)} | {_value(f.standard_errors.get(name))} |")
        lines += ["", f"![evidence for {f.effect}]({evidence_files[k]})", ""]
    lines += ["## Where the mismatch is", "",
              f"The nominal model's residual exceeds what the sensor noise explains (windowed mean square above the "
              f"chi-square quantile of pure noise) in {len(result.mismatch)} window(s), merged here into "
              f"{len(result.episodes)} episode(s), the strongest (the full list is in `diagnosis.json`):", ""]
    if result.episodes:
        lines += ["| from (s) | to (s) | signal | also in | condition | residual / noise (rms) |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {w.t_start_s:.2f} | {w.t_end_s:.2f} | {w.signal} | {', '.join(w.also_in) or '-'} | "
                  f"{w.condition} | {w.residual_rms_noise_units:.1f} |" for w in result.episodes]
    else:
        lines.append("none: the nominal model explains the recording up to noise.")
    lines += ["", "## Candidates screened and tested", "", f"Test: {result.test}.", ""]
    if result.candidates:
        lines += ["| effect | screening score | refitted | validation fit (%) | kept | outcome |", "|---|---|---|---|---|---|"]
    else:
        lines.append("none screened (see the test above).")
    for c in result.candidates:
        lines.append(f"| {c.effect} | {_value(c.score)} | {'yes' if c.refitted else 'no'} | "
                     f"{_value(c.fit_percent)} | {'yes' if c.kept else 'no'} | {c.status} |")
    if result.window_sets:
        lines += ["", "## Effects fitted together on the mismatch window", "",
                  "No effect alone explained the window where the nominal model's residual is largest; these sets "
                  "were pre-fitted together there from the data sheet (objective: residuals and the continuity "
                  "defects left open, rms in noise units; criterion N ln C + k ln N, lower is better), the best "
                  f"{SETS_SHOWN}:", "", "| effects | objective / noise | criterion | fitted whole |",
                  "|---|---|---|---|"]
        lines += [f"| {w['variants']} | {_value(w.get('window_objective_normalised'))} | {_value(w.get('criterion'))} "
                  f"| {w.get('fitted_whole', '-')} |" for w in result.window_sets[:SETS_SHOWN]]
    lines += _rescue_lines(result.rescues)
    lines += ["", "## Nominal parameters, fitted without and with the findings", "",
              "Without the missing physics, the nominal parameters bend to make up for it; with the findings "
              "modelled they move back toward physical values.", "",
              "| parameter | without the findings | with the findings | change (%) |", "|---|---|---|---|"]
    for k, v in result.nominal["parameters"].items():
        after = result.final_parameters.get(k)
        change = (100.0 * (after - v) / abs(v) if after is not None and v and math.isfinite(v) and math.isfinite(after)
                  else None)
        lines.append(f"| `{k}` | {_value(v)} | {_value(after)} | {_value(change)} |")
    lines += ["", f"Diagnosis time {result.seconds:.0f} s. The JSON result is `diagnosis.json`.", ""]
    return "\n".join(lines)


def _rescue_lines(rescues: list) -> list[str]:
    """The fits fitted again with the fit's rescue routes, as report lines (none where none was)."""
    if not rescues:
        return []
    lines = ["", "## Fitted again with the rescue routes", "",
             "The candidates' fits from the data sheet skip the fit's rescue routes; the fit the search goes on from, "
             "and the one `other` is said on, are fitted again with them where they end above noise, and the new "
             "fit is kept where it ends lower on the estimation part (residual rms in noise units).", "",
             "| where | effects | validation fit before (%) | after (%) | estimation rms before | after | kept | "
             "s | outcome |", "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['where']} | {', '.join(r['effects'])} | {_value(r.get('fit_percent_before'))} | "
              f"{_value(r.get('fit_percent_after'))} | {_value(r.get('estimation_rms_before'))} | "
              f"{_value(r.get('estimation_rms_after'))} | {'yes' if r.get('kept') else 'no'} | "
              f"{r.get('seconds', 0.0):.0f} | {r.get('outcome', '')} |" for r in rescues]
    return lines


def _other_lines(f) -> list:
    """The ``other`` finding's episodes and closest vocabulary candidates, as report lines."""
    lines = ["| from (s) | to (s) | signal | condition |", "|---|---|---|---|"]
    lines += [f"| {w.t_start_s:.2f} | {w.t_end_s:.2f} | {w.signal} | {w.condition} |" for w in f.mismatch]
    lines += ["", "Closest vocabulary candidates, and why each was rejected:", ""]
    if f.closest:
        lines += ["| effect | validation fit (%) | why rejected |", "|---|---|---|"]
        lines += [f"| {c['effect']} | {_value(c.get('fit_percent'))} | {c['why_rejected']} |" for c in f.closest]
    else:
        lines.append("none was screened.")
    return lines + [""]


def _html(markdown: str, title: str) -> str:
    """A small Markdown-to-HTML conversion of the report's own constructs (headings, tables, images)."""
    import re

    out = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
           "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;line-height:1.4}"
           "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;font-size:90%}"
           "img{max-width:100%}code{background:#eee;padding:0 3px}</style></head><body>"]
    table = []

    def inline(text):
        text = html.escape(text)
        text = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", text)
        return re.sub(r"`(.+?)`", r"<code>\1</code>", text)

    def flush():
        if table:
            rows = [r for r in table if not set(r.replace("|", "").strip()) <= set("-")]
            cells = [[c.strip() for c in r.strip().strip("|").split("|")] for r in rows]
            out.append("<table><tr>" + "".join(f"<th>{inline(c)}</th>" for c in cells[0]) + "</tr>")
            for r in cells[1:]:
                out.append("<tr>" + "".join(f"<td>{inline(c)}</td>" for c in r) + "</tr>")
            out.append("</table>")
            table.clear()

    for line in markdown.splitlines():
        if line.startswith("|"):
            table.append(line)
            continue
        flush()
        m = re.match(r"!\[(.*)\]\((.*)\)", line)
        if line.startswith("## "):
            out.append(f"<h2>{inline(line[3:])}</h2>")
        elif line.startswith("# "):
            out.append(f"<h1>{inline(line[2:])}</h1>")
        elif m:
            out.append(f"<p><img src='{html.escape(m.group(2))}' alt='{html.escape(m.group(1))}'></p>")
        elif line.strip():
            out.append(f"<p>{inline(line)}</p>")
    flush()
    out.append("</body></html>")
    return "\n".join(out)


def write_report(result: DiagnosisResult, folder) -> Path:
    """Write the report folder; returns the path of ``index.html`` (the file to open)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_json_atomic(folder / "diagnosis.json", result.to_dict(), indent=1, allow_nan=False)   # as write_json
    noise = noise_levels(result.nominal_fit.recording, result.nominal_fit.rig)
    plot_fit(result, folder / "fit.png")
    plot_zoom(result, folder / "zoom.png")
    plot_residuals(result, folder / "residuals.png", noise)
    evidence = []
    for k, f in enumerate(result.findings):
        if f.effect == "other":
            evidence.append(None)
            continue
        name = f"evidence-{k + 1}-{f.effect}.png"
        plot_evidence(result, k, folder / name)
        evidence.append(name)
    md = _markdown(result, evidence)
    write_text_atomic(folder / "report.md", md)
    index = folder / "index.html"
    write_text_atomic(index, _html(md, f"diagnosis of {result.recording}"))
    return index
