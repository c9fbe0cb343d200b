"""The report of an MRE run, like paper 1's results section, plus the loop's timing.

One page, written twice through the shared page writer (:func:`pneusim.plotting.write_page`):
``index.html`` (self-contained, the figures inlined: open this one) and ``report.md``.  It holds how
the run ended, the timing table (lateness p50/p99/max, overruns, latency, computation per sample), the
plant's counters (lost and late datagrams, round trip), the identified discrete transfer function of
every estimator (the form of paper 1's eqs. 9-11), and the error statistics of every h-step prediction
(paper 1's Table 1 columns).  Figures: ``response.png``, ``predictions.png`` (1/5/10-step),
``coefficients.png`` (theta over time), ``timing.png`` (lateness over time, lateness histogram,
computation per sample).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..plotting import COLOURS, colour_for, ms, new_figure, padded_range, robust_range, save_figure, write_page

__all__ = ["write_report"]


def _ms(x) -> str:
    return "n/a" if x is None else f"{x * 1e3:.3f}"


def write_report(run, comp, spec) -> Path:
    """Write ``index.html`` (self-contained), ``report.md`` and the figures into ``run.out_dir``; returns the
    path of ``index.html``."""
    res, s, out = run.result, run.summary, Path(run.out_dir)
    t = np.arange(res.n_samples) * res.sample_time_s
    y = comp.to_output(res.position_m)
    figs = [_response_figure(out, t, y, res, comp, s)]
    if res.predictions:
        figs += [_predictions_figure(out, t, y, res, comp), _coefficients_figure(out, t, res, comp)]
    figs.append(_timing_figure(out, t, res))
    blocks = _run_blocks(s, spec, res.sample_time_s) + _timing_blocks(s["timing"])
    if s["plant_counts"]:
        blocks += [("h", (2, "Plant counters")), ("ul", [f"{k}: {v}" for k, v in s["plant_counts"].items()])]
    blocks += _model_blocks(s) + _prediction_blocks(s, comp.output_unit)
    blocks += [("h", (2, "Figures"))] + [("fig", (f, cap)) for cap, f in figs]
    return write_page(blocks, out, f"MRE run: {s['name']}", markdown="report.md", html_name="index.html")


def _response_figure(out: Path, t, y, res, comp, s) -> tuple[str, str]:
    """Measured position (and reference) and the valve command over time."""
    what = "follows the reference" if comp.controller is not None else "under the command"
    fig, ax = new_figure(2, 1, title=f"{s['name']}: {s['plant']} plant, {s['mode']}: the position {what} and the "
                                     "valve command that drives it", size=(9, 5), sharex=True)
    ax[0].plot(t, y, lw=0.9, color=COLOURS["measured"], label="measured")
    if comp.controller is not None:
        ax[0].plot(t, comp.to_output(res.reference), lw=0.9, ls="--", color=COLOURS["reference"], label="reference")
        ax[0].legend(fontsize=8)
    ax[0].set_ylabel(f"position ({comp.output_unit})")
    ax[1].plot(t, res.valve_cmd_V, lw=0.8, color=COLOURS["command"])
    ax[1].set_ylabel("valve command (V)")
    ax[1].set_xlabel("time (s)")
    save_figure(fig, out / "response.png")
    return ("Response", "response.png")


def _predictions_figure(out: Path, t, y, res, comp) -> tuple[str, str]:
    """Per estimator: the actual output and its h-step predictions (top), the prediction errors (below)."""
    names = list(comp.estimators)
    fig, axes = new_figure(2 * len(names), 1, size=(9, 3.6 * len(names) + 0.8), squeeze=False, sharex=True,
                           gridspec_kw={"height_ratios": [2, 1] * len(names)},
                           title="Online h-step predictions of each estimator against the actual output; the error "
                                 "panels show what predicting further ahead costs")
    for k, name in enumerate(names):
        ax, ax_e = axes[2 * k, 0], axes[2 * k + 1, 0]
        colour = colour_for(name, "rls", getattr(comp.estimators[name], "order", None))
        ax.plot(t, y, lw=1.1, color=COLOURS["measured"], label="actual")
        ax_e.axhline(0.0, color=COLOURS["reference"], lw=0.6)
        errors = []
        for i, h in enumerate(comp.estimators[name].horizons):
            yhat = res.predictions[(name, h)]
            ls = ("-", "--", "-.", ":")[i % 4]
            ax.plot(t, yhat, lw=0.8, ls=ls, color=colour, label=f"{h}-step")
            ax_e.plot(t, y - yhat, lw=0.6, ls=ls, color=colour, label=f"{h}-step")
            errors.append(y - yhat)
        if np.isfinite(y).any():
            ax.set_ylim(*padded_range(y, 0.3))
        ax_e.set_ylim(*robust_range(errors))
        ax.set_ylabel(f"output ({comp.output_unit})")
        ax_e.set_ylabel(f"error ({comp.output_unit})")
        ax.set_title(name, fontsize=9)
        ax.legend(fontsize=7)
    axes[-1, 0].set_xlabel("time (s)")
    save_figure(fig, out / "predictions.png")
    return ("Online predictions (actual and h-step predicted output, and the prediction errors)", "predictions.png")


def _coefficients_figure(out: Path, t, res, comp) -> tuple[str, str]:
    """Per estimator: ``a1..an`` (solid) and ``b1..bn`` (dashed) over time."""
    names = list(comp.estimators)
    fig, axes = new_figure(len(names), 1, size=(9, 2.6 * len(names) + 0.8), squeeze=False, sharex=True,
                           title="Coefficients theta(t) of each online estimator over the run: where they settle "
                                 "and where they move")
    for ax, name in zip(axes[:, 0], names):
        th = res.thetas[name]
        n = th.shape[1] // 2
        for i in range(n):
            ax.plot(t, th[:, i], lw=0.8, color=f"C{i}", label=f"a{i + 1}")
        for i in range(n):
            ax.plot(t, th[:, n + i], lw=0.8, ls="--", color=f"C{i}", label=f"b{i + 1}")
        ax.set_ylabel("coefficient (-)")
        ax.set_title(f"{name}: a (solid) and b (dashed) of eq. 6", fontsize=9)
        ax.legend(fontsize=6, ncol=2)
    axes[-1, 0].set_xlabel("time (s)")
    save_figure(fig, out / "coefficients.png")
    return ("Coefficient traces theta(t)", "coefficients.png")


def _timing_figure(out: Path, t, res) -> tuple[str, str]:
    """Lateness over time and its histogram (paced runs), computation per sample."""
    late = res.lateness_s
    paced = np.isfinite(late).any()
    fig, ax = new_figure(1, 3, size=(12, 3.6), title="Loop timing: how late each sample starts against its deadline, "
                                                      "and the computation it needs" if paced else
                         "Loop timing: the computation each sample needs (fast mode: no deadlines)")
    if paced:
        ax[0].plot(t, ms(late), lw=0.5, color=COLOURS["measured"])
        ax[0].axhline(0.5 * res.sample_time_s * 1e3, color=COLOURS["arx"], lw=0.8, ls="--", label="half a sample")
        ax[0].set_ylabel("lateness (ms)")
        ax[0].set_xlabel("time (s)")
        ax[0].legend(fontsize=7)
        ax[1].hist(ms(late[np.isfinite(late)]), bins=100, log=True, color=COLOURS["measured"])
        ax[1].set_xlabel("lateness (ms)")
        ax[1].set_ylabel("samples (count)")
    else:
        for a in ax[:2]:
            a.text(0.5, 0.5, "fast mode: no deadlines", ha="center", va="center", transform=a.transAxes)
            a.axis("off")
    ax[2].hist(ms(res.compute_s[np.isfinite(res.compute_s)]), bins=100, log=True, color=COLOURS["command"])
    ax[2].set_xlabel("computation per sample (ms)")
    ax[2].set_ylabel("samples (count)")
    save_figure(fig, out / "timing.png")
    return ("Timing: lateness against the deadline, its histogram, and computation per sample", "timing.png")


def _run_blocks(s: dict, spec: dict, ts: float) -> list:
    """How the run went: plant, mode, why it stopped, samples, the recording."""
    blocks = [("h", (1, f"MRE run: {s['name']}"))]
    description = (spec["mre"]["description"] or "").strip()
    if description:
        blocks.append(("p", description))
    items = [f"plant: `{s['plant']}`; mode: {s['mode']} (pacing: {s['pacing']}); sample time {ts * 1e3:g} ms",
             f"stopped: **{s['stop_reason']}**" + (f" ({s['error']})" if s["error"] else ""),
             f"samples recorded: {s['samples']} of {s['samples_planned']}; held (plant gave no fresh "
             f"measurement): {s['held_samples']}; valve sent to null at the end: {'yes' if s['valve_to_null'] else 'no (a simulated plant has no valve to hold)'}",
             f"recording: `{s['recording']}` (pneusim-recording/1; `pneusim check` reads it)"]
    if s["plant"].startswith("replay:"):
        items.append("**open loop: the measurements are played back from the recording; the loop's commands "
                     "do not act on them**")
    return blocks + [("ul", items)]


def _timing_blocks(tm: dict) -> list:
    """The timing table (lateness, latency, computation per sample) and the overruns."""
    rows = []
    for key, label in (("lateness_s", "lateness (start - deadline)"), ("latency_s", "latency (measurement to command)"),
                       ("compute_s", "computation per sample")):
        v = tm[key]
        rows.append([label, _ms(v and v["p50"]), _ms(v and v["p99"]), _ms(v and v["max"]), _ms(v and v["mean"])])
    return [("h", (2, "Timing")),
            ("table", (["quantity", "p50 (ms)", "p99 (ms)", "max (ms)", "mean (ms)"], rows)),
            ("p", f"Overruns (work ended after the next deadline): {tm['overruns']}; samples late by more than half "
                  f"a sample: {tm['late_half_sample']} ({tm['late_half_sample_percent']:.3g} %).")]


def _model_blocks(s: dict) -> list:
    """Each estimator's transfer function at the end of the run (the form of paper 1's eqs. 9-11)."""
    blocks = [("h", (2, "Identified discrete transfer functions (end of run, form of paper 1 eqs. 9-11)")),
              ("p", "theta = [a1..an, b1..bn] of eq. 6; printed as G(z) = (b1 z^n + ... + bn z) / (z^n + a1 z^(n-1) "
                    "+ ... + an), the way the paper prints its results (B(z^-1)/A(z^-1) of eq. 6 is the same "
                    "divided by z).")]
    for name, mdl in s["identified"].items():
        blocks += [("p", f"**{name}** (order {mdl['order']}):"),
                   ("code", mdl["transfer_function"] + "\ntheta = [" + " ".join(f"{v:.5g}" for v in mdl["theta"]) + "]")]
    return blocks


def _prediction_blocks(s: dict, unit: str) -> list:
    """The error statistics of every h-step prediction (paper 1's Table 1 columns)."""
    rows = [[f"`{col}`", p["estimator"], p["h"], f"{p['square_error']:.4g}", f"{p['error_std']:.4g}",
             f"{p['error_min']:.4g}", f"{p['error_max']:.4g}"]
            for col, p in s["predictions"].items() if "square_error" in p]
    return [("h", (2, "Predictions (paper 1 Table 1 columns, whole run)")),
            ("table", (["column", "estimator", "h", f"square error ({unit}^2)", f"error std ({unit})", "error min",
                        "error max"], rows))]
