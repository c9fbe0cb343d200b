"""The report folder of a diagnosis: ``index.html`` (open this one: self-contained, its figures inlined),
``report.md``, the figures, ``diagnosis.json``.

The page says, in order: the verdict (what is missing, most important first; ``other`` in plain words; whether
the time budget stopped the diagnosis); the validation fit of each model; ``fit.png`` (measured, nominal and
with the findings, their errors, and a zoom on the strongest mismatch episode); ``residuals.png`` (the
residuals before and after in units of the sensor noise); per finding its evidence, its parameters and its
evidence plot (:mod:`.evidence`: the signature that identifies it, drawn where it shows); for ``other`` where
the unexplained residual is, its signature numbers and the closest candidates with why each was rejected; the
nominal parameters from the data sheet, fitted without the findings and with them (missing physics bends a
fit: the lesson is in that table); the mismatch episodes; every candidate screened; where the time went.
Every figure goes through the figure standard (:mod:`pneusim.plotting`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..model.effects import EFFECTS
from ..plotting import COLOURS, Curve, Signal, bar_gauge, compare_figure, mm, new_figure, save_figure, write_page
from .evidence import Compared, evidence_figure
from .locate import named_states
from .refits import noise_levels
from .result import DiagnosisResult

__all__ = ["write_report", "plot_fit", "plot_residuals"]


def _value(v, fmt: str = ".4g") -> str:
    if isinstance(v, str):
        return v
    return format(v, fmt) if v is not None and math.isfinite(v) else "n/a"


def _improved(result: DiagnosisResult) -> bool:
    return result.final_fit is not None and result.final_fit is not result.nominal_fit


def _with_label(result: DiagnosisResult) -> str:
    names = [f.effect for f in result.findings if f.effect != "other"]
    return "with " + " + ".join(names) if names else "nominal"


def _window(result: DiagnosisResult):
    """The strongest mismatch episode, ``(t0, t1)``, or None."""
    if not result.mismatch:
        return None
    w = max(result.mismatch, key=lambda w: w.score)
    return (w.t_start_s, w.t_end_s) if w.t_end_s > w.t_start_s else None


def plot_fit(result: DiagnosisResult, path) -> Path:
    """Measured position (and pressures) against the nominal model and the model with the findings, their
    errors, and a zoom on the strongest mismatch episode."""
    rec = result.nominal_fit.recording
    nom, fin = named_states(result.nominal_fit), named_states(result.final_fit)
    atm = float(result.nominal_fit.rig.params.get("atmosphere_Pa", 101325.0))
    rows = [("position_m", mm, "position (mm)", "mm")]
    if rec.has_pressures:
        rows += [(name, lambda p: bar_gauge(p, atm), f"{label} (bar gauge)", "bar")
                 for name, label in (("pressure_a_Pa", "p_A"), ("pressure_b_Pa", "p_B"))]
    signals = []
    for name, scale, label, unit in rows:
        curves = [Curve("nominal", scale(nom[name]), result.nominal["fit_percent"] if name == "position_m" else None,
                        color=COLOURS["nominal"], ls="--")]
        if _improved(result):
            curves.append(Curve(_with_label(result), scale(fin[name]),
                                result.final_fit_percent if name == "position_m" else None, color=COLOURS["improved"]))
        signals.append(Signal(scale(getattr(rec, name)), curves, label, unit))
    fig, _ = compare_figure(rec.time_s, signals=signals, split_s=result.validation["t_start_s"], window=_window(result),
                            title=f"{result.recording}: measured against the nominal model and "
                                  f"{'the model ' + _with_label(result) if _improved(result) else 'nothing better'} "
                                  "(validation fit in the legend)")
    return save_figure(fig, path)


def plot_residuals(result: DiagnosisResult, path, noise: dict) -> Path:
    """The residuals before (nominal) and after (with the findings), in units of the sensor noise, the mismatch
    episodes shaded."""
    rec = result.nominal_fit.recording
    t = rec.time_s
    nom, fin = named_states(result.nominal_fit), named_states(result.final_fit)
    names = ["position_m"] + (["pressure_a_Pa", "pressure_b_Pa"] if rec.has_pressures else [])
    labels = {"position_m": "position", "pressure_a_Pa": "p_A", "pressure_b_Pa": "p_B"}
    fig, axes = new_figure(len(names), 1, title="Residuals in units of the sensor noise: the nominal model and the "
                                                "model with the findings (dotted: 3 noise stds; shaded: mismatch "
                                                "episodes)", size=(9.0, 2.3 * len(names) + 0.7), squeeze=False,
                           sharex=True)
    for ax, name in zip(axes[:, 0], names):
        y, s = getattr(rec, name), noise[name]
        ax.plot(t, (y - nom[name]) / s, lw=0.6, color=COLOURS["nominal"], label="nominal")
        if _improved(result):
            ax.plot(t, (y - fin[name]) / s, lw=0.6, color=COLOURS["improved"], label=_with_label(result))
        for k in (-3, 3):
            ax.axhline(k, color=COLOURS["reference"], lw=0.6, ls=":")
        for w in result.mismatch:
            ax.axvspan(w.t_start_s, w.t_end_s, color=COLOURS["window"], alpha=0.4, lw=0)
        ax.axvline(result.validation["t_start_s"], color=COLOURS["reference"], ls=":", lw=1)
        ax.set_ylabel(f"{labels[name]} residual (noise stds)")
    axes[0, 0].legend(fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    return save_figure(fig, path)


def _other_figure(result: DiagnosisResult, path) -> Path:
    """Where the residual nothing in the vocabulary explains is: the strongest episode, measured and the model
    with the findings."""
    c = Compared(result.nominal_fit.recording, result.final_fit.rig, result.nominal_fit, result.final_fit,
                 "nominal", _with_label(result))
    other = next(f for f in result.findings if f.effect == "other")
    w = max(other.mismatch, key=lambda w: w.score)
    t = c.t
    a = int(np.searchsorted(t, w.t_start_s))
    b = max(int(np.searchsorted(t, w.t_end_s)), a + 20)
    pad = max(10, (b - a) // 4)
    a, b = max(0, a - pad), min(t.size, b + pad)
    fig, ax = new_figure(title=f"other: the strongest stretch the vocabulary does not explain ({t[a]:.1f}-"
                               f"{t[b - 1]:.1f} s, {w.condition})", size=(8.0, 4.2))
    ax.plot(t[a:b], mm(c.recording.position_m[a:b]), color=COLOURS["measured"], lw=1.2, label="measured")
    for states, lab, colour, ls in c.models():
        ax.plot(t[a:b], mm(states["position_m"][a:b]), color=colour, ls=ls, lw=1.0, label=lab)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position (mm)")
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def _finding_blocks(result: DiagnosisResult, k: int, folder: Path) -> list:
    f = result.findings[k]
    name = f"evidence-{k + 1}-{f.effect}.png"
    if f.effect == "other":
        _other_figure(result, folder / name)
        rows = [[f"{w.t_start_s:.2f}-{w.t_end_s:.2f}", w.signal, w.condition] for w in f.mismatch]
        return [("h", (2, f"{k + 1}. Something not in the vocabulary (`other`)")),
                ("p", f.evidence),
                ("table", (["time (s)", "signal", "condition"], rows)),
                ("table", (["signature of what is left", "value"],
                           [[key, _value(v, ".3g")] for key, v in f.signatures.items()])),
                ("table", (["closest vocabulary effect", "validation fit (%)", "why it was rejected"],
                           [[c["effect"], _value(c.get("fit_percent"), ".2f"), c["why_rejected"]]
                            for c in f.closest])),
                ("fig", (name, f"where the vocabulary does not explain the recording ({f.effect})"))]
    without = result.fits_without.get(f.effect, result.nominal_fit)
    others = [g.effect for g in result.findings if g.effect not in (f.effect, "other")]
    label = f"without it (with {' + '.join(others)})" if others else "without it (nominal)"
    kind = EFFECTS[f.effect].evidence_plot
    evidence_figure(kind, Compared(result.nominal_fit.recording, result.final_fit.rig, without, result.final_fit,
                                   label, _with_label(result)), f.effect, folder / name)
    rows = [[f"`{p}`", _value(v), _value(f.standard_errors.get(p))] for p, v in f.parameters.items()]
    return [("h", (2, f"{k + 1}. `{f.effect}`: the validation fit loses {f.improvement_points:.2f} points without it")),
            ("p", f"Evidence: {f.evidence}"),
            ("table", (["parameter", "estimate", "standard error"], rows)),
            ("fig", (name, f"{f.effect}: {kind}, without it and with every finding"))]


def _parameter_table(result: DiagnosisResult) -> tuple:
    """The nominal parameters: data sheet, fitted without the findings, fitted with them (with standard errors)."""
    sheet = result.nominal_fit.rig.params
    final = result.final_fit if _improved(result) else None
    rows = []
    for name, v in result.nominal["parameters"].items():
        after = final.parameters.get(name) if final is not None else None
        rows.append([f"`{name}`", _value(sheet.get(name)), _value(v),
                     f"{_value(after.estimate)} +- {_value(after.std, '.2g')}" if after is not None else "-"])
    return (["parameter", "data sheet", "fitted, nominal model", "fitted, " + _with_label(result)], rows)


def _blocks(result: DiagnosisResult, folder: Path) -> list:
    d = result.to_dict()
    names = [f.effect for f in result.findings]
    if not names:
        verdict = "**Nothing is missing**: no vocabulary effect improved the held-out fit by more than noise explains."
    else:
        verdict = "**Physics left out**, most important first: " + ", ".join(f"`{n}`" for n in names) + "."
        if "other" in names:
            verdict += " `other` is something not in the vocabulary: where and under which conditions is below."
    if result.status != "complete":
        verdict += f" **The diagnosis was {result.status}**; the findings are those made by then."
    fits = [["nominal (fitted)", f"{result.nominal['fit_percent']:.2f}"]]
    fits += [[f"without `{n}` (the other findings in)", _value(result.fits_without[n].fit_percent, ".2f")]
             for n in names if n in result.fits_without and len(result.fits_without) > 1]
    if _improved(result):
        fits.append([_with_label(result), f"{result.final_fit_percent:.2f}"])
    blocks = [("h", (1, f"Mismatch diagnosis of {result.recording}")),
              ("p", f"Rig `{result.rig}`; validation window {d['validation']['t_start_s']:.2f}-"
                    f"{d['validation']['t_end_s']:.2f} s (never used for fitting)."),
              ("h", (2, "Verdict")), ("p", verdict),
              ("table", (["model", "validation fit of the position (%)"], fits)),
              ("fig", ("fit.png", "measured against the nominal model and the model with the findings")),
              ("fig", ("residuals.png", "residuals before and after, in units of the sensor noise"))]
    for k in range(len(result.findings)):
        blocks += _finding_blocks(result, k, folder)
    blocks += [("h", (2, "The nominal parameters, from the data sheet, fitted without the findings and with them")),
               ("p", "Missing physics bends a fit: the nominal parameters take whatever values make up for it. With "
                     "the findings in, they move back towards the rig's."),
               ("table", _parameter_table(result)),
               ("h", (2, "Where the mismatch is")),
               ("p", "Episodes where the nominal model's residual exceeds what the sensor noise explains (windows "
                     "whose mean square is above the chi-square quantile of pure noise, merged)."),
               ("table", (["from (s)", "to (s)", "signal", "condition"],
                          [[f"{w.t_start_s:.2f}", f"{w.t_end_s:.2f}", w.signal, w.condition] for w in result.mismatch]))
               if result.mismatch else ("p", "none: the nominal model explains the recording up to noise."),
               ("h", (2, "Candidates screened and tested")), ("p", f"Test: {result.test}."),
               ("table", (["effect", "screening score", "refitted", "validation fit (%)", "kept", "outcome"],
                          [[c.effect, _value(c.score, ".0f"), "yes" if c.refitted else "no",
                            _value(c.fit_percent, ".2f"), "yes" if c.kept else "no", c.status]
                           for c in result.candidates])),
               ("h", (2, "Where the time went")), ("p", _timing_text(result))]
    return blocks


def _timing_text(result: DiagnosisResult) -> str:
    timing = result.timing
    stages = ", ".join(f"{k[:-2].replace('_', ' ')} {v:.0f} s" for k, v in timing.items()
                       if k.endswith("_s") and k not in ("total_s", "cpu_s") and isinstance(v, (int, float)))
    return (f"{result.seconds:.0f} s in all ({timing.get('cpu_s', math.nan):.0f} s of CPU time): {stages}. "
            "The JSON result is `diagnosis.json`.")


def write_report(result: DiagnosisResult, folder) -> Path:
    """Write the report folder; returns the path of ``index.html`` (the file to open)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    result.write_json(folder / "diagnosis.json")
    noise = noise_levels(result.nominal_fit.recording, result.nominal_fit.rig)
    plot_fit(result, folder / "fit.png")
    plot_residuals(result, folder / "residuals.png", noise)
    blocks = _blocks(result, folder)
    return write_page(blocks, folder, f"diagnosis of {result.recording}", markdown="report.md",
                      html_name="index.html")
