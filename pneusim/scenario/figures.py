"""The PNG figures of a scenario report (matplotlib, Agg backend)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..plots import plot_recording
from .tables import unit_label

__all__ = ["make_figures", "slug", "pyplot"]


def slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (files only), imported on first use: matplotlib takes about a
    second to import and only reports draw."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _limits(y, pad=0.6):
    lo, hi = float(np.nanmin(y)), float(np.nanmax(y))
    span = hi - lo or 1.0
    return lo - pad * span, hi + pad * span


def _prediction(path, t, y, yhat, title, unit):
    """The paper's figures 5-9: actual and predicted output, and the error, over time."""
    plt = pyplot()
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


def _published_z(path, t, y, pub, ours, unit):
    """Free runs of the published discrete models (and ours) on top, their one-step errors below."""
    plt = pyplot()
    fig, ax = plt.subplots(2, 1, sharex=True, figsize=(9, 5.6), gridspec_kw={"height_ratios": [3, 2]})
    ax[0].plot(t, y, lw=1.3, color="k", label="actual output (simulated rig)")
    for r in ours:
        ax[0].plot(t, r["_free"], lw=0.9, ls="--", label=f"ours, {r['identifier']} (final theta): "
                                                           f"{r['free_run_fit_percent']:.1f} %")
    first = {}
    for r in pub:
        first.setdefault(r["identifier"], r)
    for r in first.values():
        ax[0].plot(t, r["_free"], lw=0.8, label=f"{r['identifier']}: {r['free_run_fit_percent']:.1f} %")
    ax[0].set_ylim(*_limits(y, 0.4))
    ax[0].set_ylabel(f"output ({unit})")
    ax[0].set_title("free run: the model driven by the valve command alone (fit %)", fontsize=9)
    ax[0].legend(fontsize=7, loc="upper left", ncol=2)
    offsets = sorted({r.get("input_offset", 0.0) for r in pub})
    off = offsets[-1]
    for r in pub:
        if r.get("input_offset", 0.0) == off and r.get("input_delay_samples", 0) == 0:
            ax[1].plot(t, y - r["_yhat"], lw=0.6, label=f"{r['identifier']}: {r['fit_percent']:.2f} %")
    ax[1].set_ylabel(f"error ({unit})")
    ax[1].set_title(f"one-step prediction error, reading 'as printed'{f', u - {off:g} V' if off else ''} (fit %)",
                    fontsize=9)
    ax[1].legend(fontsize=7, loc="lower right")
    ax[1].set_xlabel("time (s)")
    fig.suptitle("Published discrete models (paper 1, eqs. 9-11) on our data", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _validation(path, t, y, rows, unit):
    """Validation data with each model's simulated output, and each model's error."""
    plt = pyplot()
    fig, ax = plt.subplots(2, 1, sharex=True, figsize=(9, 5.4), gridspec_kw={"height_ratios": [3, 2]})
    ax[0].plot(t, y, lw=1.4, color="k", label="measured (simulated rig)")
    for i, r in enumerate(rows):
        fit = r.get("fit_percent")
        label = r["identifier"] + (f": {fit:.1f} %" if fit is not None and np.isfinite(fit) else "")
        ax[0].plot(t, r["_yhat"], lw=0.8, color=f"C{i}", label=label)
        ax[1].plot(t, y - r["_yhat"], lw=0.6, color=f"C{i}")
    ax[0].set_ylim(*_limits(y, 0.35))
    ax[0].set_ylabel(f"output ({unit})")
    ax[0].legend(fontsize=7, loc="upper left", ncol=3)
    ax[1].set_ylabel(f"error ({unit})")
    ax[1].set_xlabel("time (s)")
    fig.suptitle("Validation half: measured output and the simulated output of each model (fit %)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _published_s(path, t, y, rows, unit):
    """One panel per time-unit reading of eq. 4 against the measured output."""
    plt = pyplot()
    fig, axes = plt.subplots(len(rows), 1, sharex=True, figsize=(9, 1.9 * len(rows) + 0.8), squeeze=False)
    for ax, r in zip(axes[:, 0], rows):
        ax.plot(t, y, lw=1.2, color="k", label="measured")
        ax.plot(t, r["_yhat"], lw=0.8, color="C1", label="eq. 4")
        lo, hi = _limits(y, 1.0)
        yl = np.clip(np.nanmin(r["_yhat"]), lo - 2 * (hi - lo), lo), np.clip(np.nanmax(r["_yhat"]), hi,
                                                                              hi + 2 * (hi - lo))
        ax.set_ylim(*yl)
        ax.set_ylabel(f"y ({unit})")
        ax.set_title(f"{r['reading']}: delay {r['delay_s']:g} s, fit {r.get('fit_percent', float('nan')):.1f} %; "
                     f"{r.get('behaviour', '')}", fontsize=8)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("Published continuous model (paper 2, eq. 4) on the validation half, per time-unit reading",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def make_figures(result, out: Path) -> list[tuple[str, str]]:
    """Draw the PNG figures into ``out``; returns ``[(file name, caption)]``."""
    figs = []
    rec, unit = result.recording, unit_label(result.spec["data"]["output_unit"])
    plot_recording(rec, out / "recording.png", title=f"{result.spec['scenario']['name']}: simulated run")
    figs.append(("recording.png", "The simulated run: position (and reference), valve command, chamber pressures."))
    t, n_est = rec.time_s, result.n_estimation
    for r in result.rows:
        if r.get("kind") == "rls" and "_yhat" in r:
            name = f"rls-{slug(r['identifier'])}-h{r['horizon']}.png"
            _prediction(out / name, t, result.y, r["_yhat"],
                        f"{r['identifier']}, {r['horizon']}-step prediction: actual, predicted and error "
                        f"(square error {r['square_error']:.3g} {unit}^2)", unit)
            figs.append((name, f"On-line actual output, {r['identifier']} at {r['horizon']}-step prediction, and "
                               "the error versus time (as the paper's figures 5-9)."))
    pub_z = [r for r in result.rows if r.get("kind") == "published_z" and "_free" in r]
    if pub_z:
        ours = [r for r in result.rows if r.get("kind") == "rls" and "_free" in r
                and np.all(np.isfinite(r["_free"]))]
        ours = [max(ours, key=lambda r: r.get("free_run_fit_percent", -np.inf))] if ours else []
        _published_z(out / "published-z.png", t, result.y, pub_z, ours, unit)
        figs.append(("published-z.png", "Paper 1's published models (eqs. 9-11) on our data: driven by the valve "
                                        "command alone (top) and predicting one step ahead (error, bottom)."))
    val_rows = [r for r in result.rows if "_yhat" in r and r.get("kind") not in ("rls", "published_z")
                and len(r["_yhat"]) == len(t) - n_est]
    blackbox = [r for r in val_rows if r["kind"] != "published_s"]
    if blackbox:
        _validation(out / "validation.png", t[n_est:], result.y[n_est:], blackbox, unit)
        figs.append(("validation.png", "Validation half: measured output, each identified model's simulated "
                                       "output (top) and its error (bottom)."))
    pub_s = [r for r in val_rows if r["kind"] == "published_s"]
    if pub_s:
        _published_s(out / "published-s.png", t[n_est:], result.y[n_est:], pub_s, unit)
        figs.append(("published-s.png", "Equation 4 simulated on the validation half under each time-unit reading "
                                        "(vertical axes clipped to three times the measured range)."))
    for v in result.variants:
        name = f"variant-{slug(v['name'])}.png"
        plot_recording(v["recording"], out / name, title=f"variant: {v['name']}")
        figs.append((name, f"Variant '{v['name']}': {v['description']}"))
    return figs
