"""The PNG figures of a scenario report, in the figure standard of :mod:`pneusim.plotting`."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..plots import plot_recording
from ..plotting import (COLOURS, Curve, compare_figure, fit_label, model_styles, new_figure, padded_range, pyplot,
                        save_figure)
from .tables import unit_label

__all__ = ["make_figures", "slug", "pyplot", "output_label"]

_OUTPUT_NAMES = {"sensor_V": "position sensor"}


def slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def output_label(output_unit: str) -> str:
    """The identification output with its unit, for an axis: ``"position sensor (V)"``, ``"position (cm)"``."""
    return f"{_OUTPUT_NAMES.get(output_unit, 'position')} ({unit_label(output_unit)})"


def _prediction(path, t, y, yhat, name, horizon, square_error, unit, ylabel):
    """The paper's figures 5-9: actual and predicted output, and the error, over time (zoomed where the
    prediction misses most)."""
    fig, _ = compare_figure(
        t, y, [Curve(f"{name}, {horizon}-step prediction", yhat, None, "rls")],
        title=f"{name}: {horizon}-step prediction against the actual output (square error {square_error:.3g} "
              f"{unit}^2); the error panel and the zoom show where it misses",
        ylabel=ylabel, unit=unit, measured_label="actual output")
    save_figure(fig, path)


def _published_z(path, t, y, pub, ours, unit, ylabel):
    """Free runs of the published discrete models (and ours) on top, their one-step errors below."""
    free = [r["free_run_fit_percent"] for r in pub if np.isfinite(r.get("free_run_fit_percent", np.nan))]
    step = [r["fit_percent"] for r in pub if np.isfinite(r.get("fit_percent", np.nan))]
    point = ("one step ahead they predict well (bottom), driven by the valve command alone they do not (top)"
             if free and step and min(step) > max(free) + 20.0 else
             "driven by the valve command alone (top) and one step ahead (bottom)")
    fig, ax = new_figure(2, 1, title=f"Paper 1's published models (eqs. 9-11) on our data: {point}",
                         size=(10, 6.2), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    ax[0].plot(t, y, lw=1.3, color=COLOURS["measured"], label="actual output (simulated rig)", zorder=3)
    for r in ours:
        ax[0].plot(t, r["_free"], lw=1.0, ls="--", color=COLOURS["rls"],
                   label=fit_label(f"ours, {r['identifier']} (final theta)", r["free_run_fit_percent"]))
    first = {}
    for r in pub:
        first.setdefault(r["identifier"], r)
    styles = model_styles(list(first), ["published_z"] * len(first))
    for name, r in first.items():
        ax[0].plot(t, r["_free"], lw=0.9, color=styles[name]["color"], ls=styles[name]["ls"],
                   label=fit_label(name, r["free_run_fit_percent"]))
    ax[0].set_ylim(*padded_range(y, 0.3))
    ax[0].set_ylabel(ylabel)
    ax[0].set_title("free run: the model driven by the valve command alone (fit % in the legend)", fontsize=9)
    ax[0].legend(fontsize=7)
    offsets = sorted({r.get("input_offset", 0.0) for r in pub})
    off = offsets[-1]
    ax[1].axhline(0.0, color=COLOURS["reference"], lw=0.6)
    for r in pub:
        if r.get("input_offset", 0.0) == off and r.get("input_delay_samples", 0) == 0:
            st = styles.get(r["identifier"], {"color": COLOURS["published"], "ls": "-"})
            ax[1].plot(t, y - r["_yhat"], lw=0.6, color=st["color"], ls=st["ls"],
                       label=fit_label(r["identifier"], r["fit_percent"], 2))
    ax[1].set_ylabel(f"error ({unit})")
    ax[1].set_title(f"one-step prediction error, reading 'as printed'{f', u - {off:g} V' if off else ''} "
                    "(fit % in the legend)", fontsize=9)
    ax[1].legend(fontsize=7)
    ax[1].set_xlabel("time (s)")
    save_figure(fig, path)


def _validation(path, t, y, rows, unit, ylabel):
    """Validation data with each model's simulated output, each model's error, and both zoomed."""
    curves = [Curve(r["identifier"], r["_yhat"], r.get("fit_percent"), r.get("kind")) for r in rows]
    scored = sorted((r for r in rows if np.isfinite(r.get("fit_percent", np.nan))), key=lambda r: r["fit_percent"])
    ranking = (f": best {scored[-1]['identifier']} ({scored[-1]['fit_percent']:.1f} %), worst "
               f"{scored[0]['identifier']} ({scored[0]['fit_percent']:.1f} %)" if len(scored) > 1 else "")
    fig, _ = compare_figure(
        t, y, curves, measured_label="measured (simulated rig)", ylabel=ylabel, unit=unit,
        title=f"Validation half, each model simulated from the input{ranking}; the errors (below) and the zoom "
              "(right) show where they differ")
    save_figure(fig, path)


def _published_s(path, t, y, rows, unit, ylabel):
    """One panel per time-unit reading of eq. 4 against the measured output."""
    fits = [r.get("fit_percent", np.nan) for r in rows]
    point = ("no reading of its time unit follows the measurement" if np.all(np.nan_to_num(fits, nan=-np.inf) < 50.0)
             else "one panel per reading of its time unit")
    fig, axes = new_figure(len(rows), 1, title=f"Paper 2's continuous model (eq. 4) on the validation half: {point}",
                           size=(10, 2.1 * len(rows) + 1.0), sharex=True, squeeze=False)
    for ax, r in zip(axes[:, 0], rows):
        ax.plot(t, y, lw=1.2, color=COLOURS["measured"], label="measured")
        ax.plot(t, r["_yhat"], lw=0.9, color=COLOURS["published"],
                label=fit_label(f"eq. 4, {r['reading']}", r.get("fit_percent")))
        lo, hi = padded_range(y, 1.0)
        span = hi - lo
        ax.set_ylim(np.clip(np.nanmin(r["_yhat"]), lo - 2 * span, lo),
                    np.clip(np.nanmax(r["_yhat"]), hi, hi + 2 * span))
        ax.set_ylabel(ylabel)
        ax.set_title(f"{r['reading']}: delay {r['delay_s']:g} s, fit {r.get('fit_percent', float('nan')):.1f} %; "
                     f"{r.get('behaviour', '')}", fontsize=8)
        ax.legend(fontsize=7)
    axes[-1, 0].set_xlabel("time (s)")
    save_figure(fig, path)


def make_figures(result, out: Path) -> list[tuple[str, str]]:
    """Draw the PNG figures into ``out``; returns ``[(file name, caption)]``."""
    figs = []
    rec, unit = result.recording, unit_label(result.spec["data"]["output_unit"])
    ylabel = output_label(result.spec["data"]["output_unit"])
    plot_recording(rec, out / "recording.png", title=f"{result.spec['scenario']['name']}: the simulated run "
                                                      "(position, valve command, chamber pressures)")
    figs.append(("recording.png", "The simulated run: position (and reference) in mm, valve command in V, chamber "
                                  "pressures in bar gauge."))
    t, n_est = rec.time_s, result.n_estimation
    for r in result.rows:
        if r.get("kind") == "rls" and "_yhat" in r:
            name = f"rls-{slug(r['identifier'])}-h{r['horizon']}.png"
            _prediction(out / name, t, result.y, r["_yhat"], r["identifier"], r["horizon"], r["square_error"], unit,
                        ylabel)
            figs.append((name, f"On-line actual output, {r['identifier']} at {r['horizon']}-step prediction, and "
                               "the error versus time (as the paper's figures 5-9), zoomed on the window where "
                               "the prediction misses most."))
    pub_z = [r for r in result.rows if r.get("kind") == "published_z" and "_free" in r]
    if pub_z:
        ours = [r for r in result.rows if r.get("kind") == "rls" and "_free" in r
                and np.all(np.isfinite(r["_free"]))]
        ours = [max(ours, key=lambda r: r.get("free_run_fit_percent", -np.inf))] if ours else []
        _published_z(out / "published-z.png", t, result.y, pub_z, ours, unit, ylabel)
        figs.append(("published-z.png", "Paper 1's published models (eqs. 9-11) on our data: driven by the valve "
                                        "command alone (top) and predicting one step ahead (error, bottom)."))
    val_rows = [r for r in result.rows if "_yhat" in r and r.get("kind") not in ("rls", "published_z")
                and len(r["_yhat"]) == len(t) - n_est]
    blackbox = [r for r in val_rows if r["kind"] != "published_s"]
    if blackbox:
        _validation(out / "validation.png", t[n_est:], result.y[n_est:], blackbox, unit, ylabel)
        figs.append(("validation.png", "Validation half: measured output and each identified model's simulated "
                                       "output (top, fit % in the legend), its error (bottom), and both zoomed on "
                                       "the window where the models miss most (right, shaded on the left)."))
    pub_s = [r for r in val_rows if r["kind"] == "published_s"]
    if pub_s:
        _published_s(out / "published-s.png", t[n_est:], result.y[n_est:], pub_s, unit, ylabel)
        figs.append(("published-s.png", "Equation 4 simulated on the validation half under each time-unit reading "
                                        "(vertical axes clipped to three times the measured range)."))
    for v in result.variants:
        name = f"variant-{slug(v['name'])}.png"
        plot_recording(v["recording"], out / name, title=f"Variant '{v['name']}': position, valve command and "
                                                         "chamber pressures over time")
        figs.append((name, f"Variant '{v['name']}': {v['description']}"))
    return figs
