"""The report folder of a diagnosis: ``index.html`` (open this one), ``report.md``, plots, ``diagnosis.json``.

Plots (PNG):

* ``fit.png`` -- measured position (and pressures) against the fitted nominal model and the improved
  model (all findings switched on), the mismatch episodes shaded, the validation part marked;
* ``zoom.png`` -- the same three curves over the strongest mismatch episode, where the difference can be seen;
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
from .locate import named_states, velocity_estimate
from .refits import noise_levels
from .result import DiagnosisResult
from .rules import COMMAND_MAP_BINS, COMMAND_MAP_SPAN

__all__ = ["write_report"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


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
    for ax, (name, y, scale, label) in zip(axes[:, 0], signals):
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
    """``[(name, measured, scale, label)]`` of the measured signals, in plotting units."""
    out = [("position_m", rec.position_m, 1e3, "position (mm)")]
    if rec.has_pressures:
        out += [("pressure_a_Pa", rec.pressure_a_Pa, 1e-5, "p_A (bar abs)"),
                ("pressure_b_Pa", rec.pressure_b_Pa, 1e-5, "p_B (bar abs)")]
    return out


def strongest_episode(result: DiagnosisResult):
    """The mismatch episode with the largest residual (None without one)."""
    spans = result.episodes or result.mismatch
    return max(spans, key=lambda w: w.score) if spans else None


def plot_zoom(result: DiagnosisResult, path) -> Path:
    """Measured, nominal and with-findings curves over the strongest mismatch episode (with a margin of half its
    length, at least 0.5 s, each side): the mismatch at a scale where it shows."""
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
    fig, axes = plt.subplots(len(signals), 1, sharex=True, figsize=(9, 2.6 * len(signals)), squeeze=False)
    improved = result.findings and result.final_fit is not result.nominal_fit
    for ax, (name, y, scale, label) in zip(axes[:, 0], signals):
        ax.plot(t[m], y[m] * scale, lw=1.0, color="0.2", label="measured")
        ax.plot(t[m], nom[name][m] * scale, lw=1.0, color="C0", label="nominal")
        if improved:
            ax.plot(t[m], fin[name][m] * scale, lw=1.0, color="C2", ls="--",
                    label=f"with {' + '.join(result.effects)}")
        if w is not None:
            ax.axvspan(w.t_start_s, w.t_end_s, color="C3", alpha=0.10, lw=0)
        ax.set_ylabel(label)
    where = (f"strongest mismatch episode {w.t_start_s:.2f}-{w.t_end_s:.2f} s on {w.signal} ({w.condition})"
             if w is not None else "no mismatch episode: the whole recording")
    axes[0, 0].set_title(f"{result.recording}: {where}", fontsize=9)
    axes[0, 0].legend(loc="best", fontsize=8)
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


def _binned(x, y, bins=20):
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < bins * 3:
        return np.array([]), np.array([])
    values = np.unique(x)
    if values.size <= bins:  # a few distinct levels (pulse commands): one point per level
        return values, np.array([y[x == v].mean() for v in values])
    edges = np.quantile(x, np.linspace(0, 1, bins + 1))
    centres, means = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        m = (x >= a) & (x <= b)
        if m.sum() > 2:
            centres.append(x[m].mean())
            means.append(y[m].mean())
    return np.array(centres), np.array(means)


#: which evidence plot shows each effect's signature (the residual over time for any other effect): the
#: signature its ``evidence`` text reads (an Effect fact the contract does not declare yet)
EVIDENCE_PLOTS = {
    "friction_asymmetry": "direction", "external_load": "position",
    "pressure_dependent_friction": "pressure difference", "supply_pressure_droop": "pressure difference",
    "transport_delay": "lag", "valve_dynamics": "lag", "valve_deadband": "command map", "valve_offset": "command map",
}


def _binned_residuals(ax, x, residuals, xlabel: str, ylabel: str, title: str) -> None:
    """Binned means of each ``(residual, colour, label)`` against ``x``."""
    for e, c, lab in residuals:
        cx, cy = _binned(x, e)
        ax.plot(cx, cy, "o-", color=c, label=lab, ms=3)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)


def _plot_direction(ax, result, v, x, e_nom, e_fin, nom, fin):
    _binned_residuals(ax, v * 1e3, [(e_nom * 1e3, "C0", "nominal"), (e_fin * 1e3, "C2", "with findings")],
                      "measured velocity (mm/s)", "binned mean velocity residual (mm/s)",
                      "residual against direction of motion")


def _plot_position(ax, result, v, x, e_nom, e_fin, nom, fin):
    _binned_residuals(ax, x * 1e3, [(e_nom * 1e3, "C0", "nominal"), (e_fin * 1e3, "C2", "with findings")],
                      "position (mm)", "binned mean velocity residual (mm/s)", "residual against position")


def _plot_pressure_difference(ax, result, v, x, e_nom, e_fin, nom, fin):
    rec = result.nominal_fit.recording
    if rec.has_pressures:
        dp = np.abs(rec.pressure_a_Pa - rec.pressure_b_Pa)
        xlabel = "|p_A - p_B| measured (bar)"
    else:
        dp = np.abs(nom["pressure_a_Pa"] - nom["pressure_b_Pa"])
        xlabel = "|p_A - p_B| of the nominal model (bar)"
    residuals = [(np.abs(e_nom) * 1e3, "C0", "nominal"), (np.abs(e_fin) * 1e3, "C2", "with findings")]
    _binned_residuals(ax, dp * 1e-5, residuals, xlabel, "binned mean |velocity residual| (mm/s)",
                      "residual against the pressure difference across the seal")


def _plot_lag(ax, result, v, x, e_nom, e_fin, nom, fin):
    rec = result.nominal_fit.recording
    t, u = rec.time_s, rec.valve_cmd_V
    dt = float(t[1] - t[0])
    du = np.diff(u)
    lags = np.arange(0, max(3, min(int(0.2 / dt), du.size // 4)))
    for st, c, lab in ((nom, "C0", "nominal"), (fin, "C2", "with findings")):
        dr = np.diff(np.where(np.isfinite(st["position_m"]), x - st["position_m"], 0.0))
        cc = [np.corrcoef(du[:du.size - L], dr[L:])[0, 1] if np.std(dr[L:]) > 0 else np.nan for L in lags]
        ax.plot(lags * dt * 1e3, cc, "o-", color=c, label=lab, ms=3)
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_xlabel("lag (ms)")
    ax.set_ylabel("correlation of command and residual increments (-)")
    ax.set_title("input-residual cross-correlation")


def _plot_command_map(ax, result, v, x, e_nom, e_fin, nom, fin):
    rig = result.nominal_fit.rig
    u = result.nominal_fit.recording.valve_cmd_V
    null = float(rig.params.get("valve_null_V", 5.0))
    span = float(rig.params.get("valve_max_V", 10.0) - rig.params.get("valve_min_V", 0.0))
    near = np.abs(u - null) <= COMMAND_MAP_SPAN * span
    for vv, c, lab in ((v, "0.2", "measured"), (nom["velocity_m_per_s"], "C0", "nominal"),
                       (fin["velocity_m_per_s"], "C2", "with findings")):
        cx, cy = _binned(u[near], vv[near] * 1e3, bins=COMMAND_MAP_BINS)
        ax.plot(cx, cy, "o-", color=c, label=lab, ms=3)
    ax.axvline(null, color="0.5", lw=0.5, ls=":")
    ax.axhline(0.0, color="0.5", lw=0.5)
    ax.set_xlabel(f"valve command within {COMMAND_MAP_SPAN * span:.2g} V of null (V)")
    ax.set_ylabel("binned mean velocity (mm/s)")
    ax.set_title("command-velocity map near null\n(dead band: a flat spot at zero; offset: a shifted crossing)",
                 fontsize=9)


def _plot_over_time(ax, result, v, x, e_nom, e_fin, nom, fin):
    rec = result.nominal_fit.recording
    t, s = rec.time_s, result.signatures
    ax.plot(t, (x - nom["position_m"]) * 1e3, lw=0.6, color="C0", label="nominal")
    ax.plot(t, (x - fin["position_m"]) * 1e3, lw=0.6, color="C2", label="with findings")
    if rec.has_pressures:
        ax2 = ax.twinx()
        ax2.plot(t, (rec.pressure_a_Pa - nom["pressure_a_Pa"]) * 1e-3, lw=0.4, color="C1", alpha=0.6,
                 label="p_A residual, nominal (kPa)")
        ax2.plot(t, (rec.pressure_a_Pa - fin["pressure_a_Pa"]) * 1e-3, lw=0.4, color="C4", alpha=0.6,
                 label="p_A residual, with findings (kPa)")
        ax2.set_ylabel("pressure residual (kPa)")
        ax2.legend(loc="lower right", fontsize=7)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position residual (mm)")
    ax.set_title(f"residual over time (creep near null {s.get('creep_mm_s', float('nan')):+.3f} mm/s)")


_PLOTS = {"direction": _plot_direction, "position": _plot_position, "pressure difference": _plot_pressure_difference,
          "lag": _plot_lag, "command map": _plot_command_map}


def plot_evidence(result: DiagnosisResult, k: int, path) -> Path:
    """The evidence of finding ``k``: the signature before (nominal) and after (with the findings up to k),
    as :data:`EVIDENCE_PLOTS` says for its effect."""
    plt = _plt()
    eff = result.findings[k].effect
    rec = result.nominal_fit.recording
    t, x = rec.time_s, rec.position_m
    nom, fin = named_states(result.nominal_fit), named_states(result.final_fit)
    v = velocity_estimate(t, x)
    e_nom = v - velocity_estimate(t, np.nan_to_num(nom["position_m"]))
    e_fin = v - velocity_estimate(t, np.nan_to_num(fin["position_m"]))
    fig, ax = plt.subplots(figsize=(7, 4.2))
    plot = _PLOTS.get(EVIDENCE_PLOTS.get(eff), _plot_over_time)
    plot(ax, result, v, x, e_nom, e_fin, nom, fin)
    ax.legend(fontsize=8)
    fig.suptitle(f"{k + 1}. {eff}", fontsize=10)
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)


def _value(v):
    if isinstance(v, str):
        return v
    return f"{v:.4g}" if v is not None and math.isfinite(v) else "n/a"


def _markdown(result: DiagnosisResult, evidence_files) -> str:
    d = result.to_dict()
    lines = [f"# Mismatch diagnosis of {result.recording}", "",
             f"Rig `{result.rig}`; validation window {d['validation']['t_start_s']:.2f}-{d['validation']['t_end_s']:.2f} s "
             "(never used for fitting).", "",
             "## Verdict", ""]
    named = [f for f in result.findings if f.effect != "other"]
    other = next((f for f in result.findings if f.effect == "other"), None)
    if not result.findings:
        lines.append("**Nothing is missing**: no vocabulary effect improved the held-out fit by more than noise explains.")
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
    lines += ["", "| model | validation fit of the position (%) |", "|---|---|",
              f"| nominal (fitted) | {result.nominal['fit_percent']:.2f} |"]
    acc = []
    for f in result.findings:
        acc.append(f.effect)
        lines.append(f"| nominal + {' + '.join(acc)} | {f.fit_percent:.2f} (+{f.improvement_points:.2f}) |")
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
                  f"{w.condition} | {math.sqrt(max(w.score, 0.0)):.1f} |" for w in result.episodes]
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
