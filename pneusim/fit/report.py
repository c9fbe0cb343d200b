"""Report of a fit: measured versus fitted signals with residuals, a summary in Markdown and the same page
as self-contained HTML (``index.html``, the figure inlined), as the other reports."""

from __future__ import annotations

import math
from pathlib import Path

from ..outputs import write_json_atomic
from ..plotting import Curve, Signal, bar_gauge, compare_figure, mm, save_figure, write_page
from .result import FitResult

__all__ = ["write_fit_report", "plot_fit", "fit_figure"]

#: the signals a fit is scored on: (state name, axis label, unit, conversion from SI)
_SIGNALS = (("position_m", "position (mm)", "mm", lambda x, atm: mm(x)),
            ("pressure_a_Pa", "pressure A (bar gauge)", "bar", lambda p, atm: bar_gauge(p, atm)),
            ("pressure_b_Pa", "pressure B (bar gauge)", "bar", lambda p, atm: bar_gauge(p, atm)))
_NAMES = {"position_m": "position", "pressure_a_Pa": "pressure in chamber A", "pressure_b_Pa": "pressure in chamber B"}


def _fits(result: FitResult) -> dict:
    """Validation fit % of each scored signal, ``{state name: fit}``."""
    v = result.validation
    out = {"position_m": v["fit_percent"]}
    for name in ("pressure_a_Pa", "pressure_b_Pa"):
        if f"fit_percent_{name}" in v:
            out[name] = v[f"fit_percent_{name}"]
    return out


def fit_figure(result: FitResult):
    """Measured and fitted position (and pressures) over the whole recording, residuals below, zoomed on the
    window where the model misses most; returns ``(figure, axes)``.

    The estimation part shows the fitted trajectory (multiple shooting, joined), the validation part the
    free simulation from the fitted boundary state.
    """
    rec, model, n_est = result.recording, result.model, result.n_estimation
    t = rec.time_s
    fitted = result.trajectory()
    atm = float(result.rig.params.get("atmosphere_Pa", 101325.0))
    fits = _fits(result)
    signals = []
    for name, label, unit, convert in _SIGNALS:
        measured = getattr(rec, name)
        if measured is None:
            continue
        model_y = fitted[:, model.state_names.index(name)]
        fit = fits.get(name)
        signals.append(Signal(convert(measured, atm), [Curve("physical model", convert(model_y, atm), fit,
                                                             "physical_fit")], label, unit,
                              title=f"{_NAMES[name]}: validation fit {fit:.2f} %" if fit is not None else _NAMES[name]))
    split = float(t[n_est])
    title = (f"{result.rig.name}: the fitted physical model against the recording -- validation fit "
             f"{result.fit_percent:.2f} % on {split:.1f}-{t[-1]:.1f} s, a part the fit never saw")
    return compare_figure(t, signals=signals, title=title, split_s=split)


def plot_fit(result: FitResult, path) -> Path:
    """Write :func:`fit_figure` to ``path``; returns the path."""
    fig, _ = fit_figure(result)
    return save_figure(fig, Path(path))


def _blocks(result: FitResult) -> list:
    """The report page: setup, parameters, validation fits, residual level, warnings, figure."""
    v = result.validation
    rec = result.recording
    blocks = [("h", (1, f"Physical fit of {result.recording_name}")),
              ("p", f"Rig: {result.rig.name}; effects: {', '.join(e.to_text() for e in result.effects_) or 'none'}. "
                    f"Estimation on {rec.time_s[0]:.3f}-{rec.time_s[result.n_estimation - 1]:.3f} s "
                    f"({result.n_estimation} samples), validation on {v['t_start_s']:.3f}-{v['t_end_s']:.3f} s "
                    "(never seen by the optimiser).")]
    rows = []
    for name, p in result.parameters.items():
        std = f"{p.std:.4g}" if math.isfinite(p.std) else "∞"
        rel = f"{p.relative_std:.2%}" if math.isfinite(p.relative_std) else "∞"
        rows.append([name, f"{p.start:.4g}", f"{p.estimate:.4g}", std, rel])
    blocks += [("h", (2, f"Parameters ({len(rows)} fitted)")),
               ("table", (["parameter", "start", "estimate", "std", "std / estimate"], rows))]
    fits = _fits(result)
    blocks += [("h", (2, "Validation fit (MATLAB compare)")),
               ("p", f"Position: **{fits['position_m']:.2f} %**."),
               ("table", (["signal", "validation fit (%)"],
                          [[_NAMES[name], f"{fit:.2f}"] for name, fit in fits.items()]))]
    noise = ", ".join(f"{k}: {val:.3g}" for k, val in result.sigma.items())
    ratios = ", ".join(f"{k}: {val:.3f}" for k, val in result.normalised_residuals.items())
    blocks += [("h", (2, "Residual")),
               ("ul", [f"Residual standard deviation on the estimation part: {noise} (SI units).",
                       f"Residual over sensor noise (1 = noise level): {ratios}; "
                       + ("the fit reaches the noise level." if result.converged_to_noise
                          else "**the fit ends above the noise level** (see the warnings)."),
                       f"Finished by: {result.solver.get('stopped_by', result.solver['status'])}; "
                       f"{result.solver['seconds']:.1f} s in all."])]
    if result.warnings:
        blocks += [("h", (2, "Warnings")), ("ul", list(result.warnings))]
    blocks += [("h", (2, "Figure")),
               ("fig", ("fit.png", "Measured and fitted signals (top of each pair) with residuals (below), zoomed "
                                   "on the window where the model misses most (right); validation after the dotted "
                                   "line."))]
    return blocks


def write_fit_report(result: FitResult, directory) -> Path:
    """``index.html`` (self-contained, open this one), ``report.md``, ``fit.json`` and ``fit.png`` in
    ``directory``; returns the path of ``index.html``."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out / "fit.json", result.to_dict(), indent=1)     # as FitResult.write_json, atomically
    plot_fit(result, out / "fit.png")
    return write_page(_blocks(result), out, f"Physical fit of {result.recording_name}", markdown="report.md",
                      html_name="index.html")
