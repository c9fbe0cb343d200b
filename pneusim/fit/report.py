"""Report of a fit: measured versus fitted signals with residuals, and a summary in Markdown."""

from __future__ import annotations

import math
from pathlib import Path


from .result import FitResult

__all__ = ["write_fit_report", "plot_fit"]


def plot_fit(result: FitResult, path) -> Path:
    """Measured and fitted position (and pressures) over the whole recording, residuals below.

    The estimation part shows the fitted trajectory (multiple shooting, joined),
    the validation part the free simulation from the fitted boundary state.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rec = result.recording
    model = result.model
    n_est = result.n_estimation
    t = rec.time_s
    fitted = result.trajectory()
    signals = [("position_m", rec.position_m, 1e3, "position (mm)")]
    if rec.has_pressures:
        signals += [("pressure_a_Pa", rec.pressure_a_Pa, 1e-5, "p_A (bar abs)"),
                    ("pressure_b_Pa", rec.pressure_b_Pa, 1e-5, "p_B (bar abs)")]
    fig, axes = plt.subplots(2 * len(signals), 1, sharex=True, figsize=(10, 2.2 * 2 * len(signals)),
                             gridspec_kw={"height_ratios": [2, 1] * len(signals)})
    split = t[n_est]
    for k, (name, measured, scale, label) in enumerate(signals):
        model_y = fitted[:, model.state_names.index(name)]
        ax, ax_r = axes[2 * k], axes[2 * k + 1]
        ax.plot(t, measured * scale, lw=0.7, color="0.3", label="measured")
        ax.plot(t[:n_est], model_y[:n_est] * scale, lw=0.8, color="C0", label="fitted (estimation)")
        ax.plot(t[n_est:], model_y[n_est:] * scale, lw=0.8, color="C1", label="simulated (validation)")
        ax.set_ylabel(label)
        residual = (measured - model_y) * scale
        ax_r.plot(t, residual, lw=0.5, color="C3")
        ax_r.axhline(0.0, color="0.5", lw=0.5)
        ax_r.set_ylabel("residual (" + label.split("(")[1])
        for a in (ax, ax_r):
            a.axvline(split, color="0.5", ls="--", lw=0.8)
        if k == 0:
            ax.legend(loc="upper right", fontsize=8, ncol=3)
            ax.set_title(f"{result.rig.name}: fit on {t[0]:.1f}-{t[n_est - 1]:.1f} s, validation fit "
                         f"{result.fit_percent:.2f} % on {split:.1f}-{t[-1]:.1f} s")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_fit_report(result: FitResult, directory) -> Path:
    """``report.md``, ``fit.json`` and ``fit.png`` in ``directory``."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    result.write_json(out / "fit.json")
    plot_fit(result, out / "fit.png")
    v = result.validation
    lines = [f"# Physical fit of {result.recording_name}", "",
             f"Rig: {result.rig.name}; effects: {', '.join(e.to_text() for e in result.effects_) or 'none'}.",
             f"Estimation on {result.recording.time_s[0]:.3f}-{result.recording.time_s[result.n_estimation - 1]:.3f} s "
             f"({result.n_estimation} samples), validation on {v['t_start_s']:.3f}-{v['t_end_s']:.3f} s "
             "(never seen by the optimiser).", "",
             "| parameter | start | estimate | std | std / estimate |", "|---|---|---|---|---|"]
    for name, p in result.parameters.items():
        std = f"{p.std:.4g}" if math.isfinite(p.std) else "∞"
        rel = f"{p.relative_std:.2%}" if math.isfinite(p.relative_std) else "∞"
        lines.append(f"| {name} | {p.start:.4g} | {p.estimate:.4g} | {std} | {rel} |")
    lines += ["", f"Validation fit (MATLAB compare, position): **{v['fit_percent']:.2f} %**"]
    for name in ("pressure_a_Pa", "pressure_b_Pa"):
        if f"fit_percent_{name}" in v:
            lines.append(f"; {name}: {v[f'fit_percent_{name}']:.2f} %")
    noise = ", ".join(f"{k}: {val:.3g}" for k, val in result.sigma.items())
    ratios = ", ".join(f"{k}: {val:.3f}" for k, val in result.normalised_residuals.items())
    lines += ["", f"Residual standard deviation on the estimation part: {noise} (SI units).",
              f"Residual over sensor noise (1 = noise level): {ratios}; "
              + ("the fit reaches the noise level." if result.converged_to_noise
                 else "**the fit ends above the noise level** (see the warnings)."),
              f"IPOPT: {result.solver['status']} after {result.solver['iterations']} iterations; "
              f"{result.solver['seconds']:.1f} s in all.", ""]
    if result.warnings:
        lines += ["## Warnings", ""] + [f"* {w}" for w in result.warnings] + [""]
    lines += ["![Measured and fitted signals with residuals](fit.png)", ""]
    (out / "report.md").write_text("\n".join(lines))
    return out / "report.md"
