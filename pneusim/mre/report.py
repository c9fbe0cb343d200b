"""The report of an MRE run, like paper 1's results section, plus the loop's timing.

``report.md`` holds how the run ended, the timing table (lateness p50/p99/max,
overruns, latency, computation per sample), the plant's counters (lost and late
datagrams, round trip), the identified discrete transfer function of every
estimator (the form of paper 1's eqs. 9-11), and the error statistics of every
h-step prediction (paper 1's Table 1 columns).  Figures: ``response.png``,
``predictions.png`` (1/5/10-step), ``coefficients.png`` (theta over time),
``timing.png`` (lateness over time, lateness histogram, computation per sample).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_report"]


def _plt():
    """``matplotlib.pyplot`` on the Agg backend, imported on first use (about a second; only the report draws)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _ms(x) -> str:
    return "n/a" if x is None else f"{x * 1e3:.3f}"


def write_report(run, comp, spec) -> Path:
    """Write ``report.md`` and the figures into ``run.out_dir``; returns the report's path."""
    res, s, out = run.result, run.summary, Path(run.out_dir)
    t = np.arange(res.n_samples) * res.sample_time_s
    y = comp.to_output(res.position_m)
    figs = [_response_figure(out, t, y, res, comp, s)]
    if res.predictions:
        figs += [_predictions_figure(out, t, y, res, comp), _coefficients_figure(out, t, res, comp)]
    figs.append(_timing_figure(out, t, res))
    lines = _run_lines(s, spec, res.sample_time_s) + _timing_lines(s["timing"])
    if s["plant_counts"]:
        lines += ["## Plant counters", ""] + [f"* {k}: {v}" for k, v in s["plant_counts"].items()] + [""]
    lines += _model_lines(s) + _prediction_lines(s, comp.output_unit)
    lines += ["", "## Figures", ""] + [f"![{cap}]({f})\n\n*{cap}*\n" for cap, f in figs]
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _response_figure(out: Path, t, y, res, comp, s) -> tuple[str, str]:
    """Measured position (and reference) and the valve command over time."""
    plt = _plt()
    fig, ax = plt.subplots(2, 1, sharex=True, figsize=(9, 5))
    ax[0].plot(t, y, lw=0.8, label="measured")
    if comp.controller is not None:
        ax[0].plot(t, comp.to_output(res.reference), lw=0.8, ls="--", label="reference")
    ax[0].set_ylabel(f"position ({comp.output_unit})")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[1].plot(t, res.valve_cmd_V, lw=0.8, color="C2")
    ax[1].set_ylabel("valve command (V)")
    ax[1].set_xlabel("time (s)")
    fig.suptitle(f"{s['name']}: {s['plant']} plant, {s['mode']}")
    fig.tight_layout()
    fig.savefig(out / "response.png", dpi=110)
    plt.close(fig)
    return ("Response", "response.png")


def _predictions_figure(out: Path, t, y, res, comp) -> tuple[str, str]:
    """Per estimator: the actual output and its h-step predictions."""
    plt = _plt()
    names = list(comp.estimators)
    fig, axes = plt.subplots(len(names), 1, sharex=True, figsize=(9, 2.3 * len(names)), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        ax.plot(t, y, lw=1.0, color="k", label="actual")
        for h in comp.estimators[name].horizons:
            ax.plot(t, res.predictions[(name, h)], lw=0.7, label=f"{h}-step")
        ok = np.isfinite(y)
        if ok.any():
            lo, hi = np.nanmin(y), np.nanmax(y)
            pad = 0.3 * (hi - lo + 1e-12)
            ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(comp.output_unit)
        ax.set_title(name, fontsize=9)
        ax.legend(loc="upper right", fontsize=7, ncol=4)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(out / "predictions.png", dpi=110)
    plt.close(fig)
    return ("Online predictions (actual and h-step predicted output)", "predictions.png")


def _coefficients_figure(out: Path, t, res, comp) -> tuple[str, str]:
    """Per estimator: ``a1..an`` and ``b1..bn`` over time."""
    plt = _plt()
    names = list(comp.estimators)
    fig, axes = plt.subplots(len(names), 1, sharex=True, figsize=(9, 2.3 * len(names)), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        th = res.thetas[name]
        n = th.shape[1] // 2
        for i in range(n):
            ax.plot(t, th[:, i], lw=0.8, label=f"a{i + 1}")
        for i in range(n):
            ax.plot(t, th[:, n + i], lw=0.8, ls="--", label=f"b{i + 1}")
        ax.set_title(name, fontsize=9)
        ax.legend(loc="upper right", fontsize=6, ncol=2 * n)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(out / "coefficients.png", dpi=110)
    plt.close(fig)
    return ("Coefficient traces theta(t)", "coefficients.png")


def _timing_figure(out: Path, t, res) -> tuple[str, str]:
    """Lateness over time and its histogram (paced runs), computation per sample."""
    plt = _plt()
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.2))
    late = res.lateness_s
    if np.isfinite(late).any():
        ax[0].plot(t, late * 1e3, lw=0.5)
        ax[0].axhline(0.5 * res.sample_time_s * 1e3, color="r", lw=0.8, ls="--", label="half a sample")
        ax[0].set_ylabel("lateness (ms)")
        ax[0].set_xlabel("time (s)")
        ax[0].legend(fontsize=7)
        ax[1].hist(late[np.isfinite(late)] * 1e3, bins=100, log=True)
        ax[1].set_xlabel("lateness (ms)")
        ax[1].set_ylabel("samples")
    else:
        for a in ax[:2]:
            a.text(0.5, 0.5, "fast mode: no deadlines", ha="center", va="center", transform=a.transAxes)
    ax[2].hist(res.compute_s[np.isfinite(res.compute_s)] * 1e3, bins=100, log=True, color="C1")
    ax[2].set_xlabel("computation per sample (ms)")
    fig.tight_layout()
    fig.savefig(out / "timing.png", dpi=110)
    plt.close(fig)
    return ("Timing: lateness against the deadline, its histogram, and computation per sample", "timing.png")


def _run_lines(s: dict, spec: dict, ts: float) -> list[str]:
    """How the run went: plant, mode, why it stopped, samples, the recording."""
    lines = [f"# MRE run: {s['name']}", "",
             spec["mre"]["description"].strip() if spec["mre"]["description"] else "", "",
             f"* plant: `{s['plant']}`; mode: {s['mode']} (pacing: {s['pacing']}); sample time {ts * 1e3:g} ms",
             f"* stopped: **{s['stop_reason']}**" + (f" ({s['error']})" if s["error"] else ""),
             f"* samples recorded: {s['samples']} of {s['samples_planned']}; held (plant gave no fresh "
             f"measurement): {s['held_samples']}; valve sent to null at the end: {'yes' if s['valve_to_null'] else 'no (a simulated plant has no valve to hold)'}",
             f"* recording: `{s['recording']}` (pneusim-recording/1; `pneusim check` reads it)"]
    if s["plant"].startswith("replay:"):
        lines.append("* **open loop: the measurements are played back from the recording; the loop's commands "
                     "do not act on them**")
    return lines


def _timing_lines(tm: dict) -> list[str]:
    """The timing table (lateness, latency, computation per sample) and the overruns."""
    lines = ["", "## Timing", "", "| quantity | p50 (ms) | p99 (ms) | max (ms) | mean (ms) |", "|---|---|---|---|---|"]
    for key, label in (("lateness_s", "lateness (start - deadline)"), ("latency_s", "latency (measurement to command)"),
                       ("compute_s", "computation per sample")):
        v = tm[key]
        lines.append(f"| {label} | {_ms(v and v['p50'])} | {_ms(v and v['p99'])} | {_ms(v and v['max'])} | "
                     f"{_ms(v and v['mean'])} |")
    lines += ["", f"Overruns (work ended after the next deadline): {tm['overruns']}; samples late by more than half "
                  f"a sample: {tm['late_half_sample']} ({tm['late_half_sample_percent']:.3g} %).", ""]
    return lines


def _model_lines(s: dict) -> list[str]:
    """Each estimator's transfer function at the end of the run (the form of paper 1's eqs. 9-11)."""
    lines = ["## Identified discrete transfer functions (end of run, form of paper 1 eqs. 9-11)", "",
             "theta = [a1..an, b1..bn] of eq. 6; printed as G(z) = (b1 z^n + ... + bn z) / (z^n + a1 z^(n-1) + ... "
             "+ an), the way the paper prints its results (B(z^-1)/A(z^-1) of eq. 6 is the same divided by z).", ""]
    for name, mdl in s["identified"].items():
        lines += [f"**{name}** (order {mdl['order']}):", "", "```text", mdl["transfer_function"],
                  "theta = [" + " ".join(f"{v:.5g}" for v in mdl["theta"]) + "]", "```", ""]
    return lines


def _prediction_lines(s: dict, unit: str) -> list[str]:
    """The error statistics of every h-step prediction (paper 1's Table 1 columns)."""
    lines = ["## Predictions (paper 1 Table 1 columns, whole run)", "",
             f"| column | estimator | h | square error ({unit}^2) | error std ({unit}) | error min | error max |",
             "|---|---|---|---|---|---|---|"]
    for col, p in s["predictions"].items():
        if "square_error" in p:
            lines.append(f"| `{col}` | {p['estimator']} | {p['h']} | {p['square_error']:.4g} | {p['error_std']:.4g} | "
                         f"{p['error_min']:.4g} | {p['error_max']:.4g} |")
    return lines
