"""The evidence plot of each finding: the signature that identifies its effect, before (the nominal model) and after
(with the findings), drawn where it can be seen.  Each effect names its plot (``Effect.evidence_plot``, one of
:data:`pneusim.model.effects.EVIDENCE_PLOTS`): the residual against the direction of motion for an asymmetry, against
the pressure difference for pressure-dependent friction or a supply droop, against position for a load, the
command-residual cross-correlation for a delay or a spool lag, the command-velocity map near null for a dead band or
an offset, the creep while holding for a leak, the relaxation after moves for heat transfer; ``other`` the residuals
over time."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.effects import EFFECTS
from ..outputs import savefig_atomic
from .locate import named_states, near_null, valve_null_and_span, velocity_estimate
from .result import DiagnosisResult
from .rules import COMMAND_MAP_BINS, COMMAND_MAP_SPAN, NEAR_NULL_SPAN
from .signatures import hold_runs, settling

__all__ = ["plot_evidence", "pyplot"]


def pyplot():
    """matplotlib's pyplot on the Agg backend (files only, no screen)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt



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
    u, null, span, near = _near_null(result, COMMAND_MAP_SPAN)
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


def _plot_holding(ax, result, v, x, e_nom, e_fin, nom, fin):
    """Creep while holding: the velocity where the valve is near null (within :data:`~.rules.NEAR_NULL_SPAN` of its
    span), binned by position, measured against the models; a leak or a slow pressure drift moves the piston
    there, the nominal model holds it still."""
    _, _, span, holding = _near_null(result, NEAR_NULL_SPAN)
    if holding.sum() < 60:          # never near null: the residual over time says more
        _plot_over_time(ax, result, v, x, e_nom, e_fin, nom, fin)
        return
    for vv, c, lab in ((v, "0.2", "measured"), (nom["velocity_m_per_s"], "C0", "nominal"),
                       (fin["velocity_m_per_s"], "C2", "with findings")):
        cx, cy = _binned(x[holding] * 1e3, vv[holding] * 1e3)
        ax.plot(cx, cy, "o-", color=c, label=lab, ms=3)
    ax.axhline(0.0, color="0.5", lw=0.5)
    ax.set_xlabel("position (mm)")
    ax.set_ylabel("binned mean velocity (mm/s)")
    ax.set_title(f"creep while holding: velocity with the valve within {NEAR_NULL_SPAN * span:.2g} V of null\n"
                 f"({int(holding.sum())} samples; creep near null {result.signatures.get('creep_mm_s', float('nan')):+.3f}"
                 " mm/s beyond the nominal model)", fontsize=9)


def _plot_relaxation(ax, result, v, x, e_nom, e_fin, nom, fin):
    """Relaxation after moves: how far the residual has moved since the valve came back near null (within
    :data:`~.rules.NEAR_NULL_SPAN` of its span), against the time since then.  Heat exchange with the walls lets a
    chamber's pressure settle back after each move, for a few time constants; a model without it holds the pressure
    where the move left it, and its residual grows there (:func:`~.signatures.settling`: signed by the move's own
    change, so that the sensor noise averages out); the chamber pressures where recorded (the mean of both), the
    position otherwise."""
    rec = result.nominal_fit.recording
    _, _, _, near = _near_null(result, NEAR_NULL_SPAN)
    since, stop, start = hold_runs(near, rec.time_s)
    held = stop >= 0
    if held.sum() < 60:             # hardly ever back at null after a move: the residual over time says more
        _plot_over_time(ax, result, v, x, e_nom, e_fin, nom, fin)
        return
    names = ("pressure_a_Pa", "pressure_b_Pa") if rec.has_pressures else ("position_m",)
    scale, unit = (1e-3, "kPa") if rec.has_pressures else (1e3, "mm")

    def settled(states):
        """Mean over ``names`` of :func:`~.signatures.settling` at the held samples."""
        return np.mean([settling(getattr(rec, n), states[n], stop, start)[held] for n in names], axis=0) * scale

    signal = "pressure" if rec.has_pressures else "position"
    _binned_residuals(ax, since[held], [(settled(nom), "C0", "nominal"), (settled(fin), "C2", "with findings")],
                      "time since the valve came back near null (s)",
                      f"{signal} residual's change since then,\nsigned by the move's {signal} change ({unit})",
                      f"relaxation after moves ({len(np.unique(stop[held]))} stops): a model that misses it drifts "
                      "from zero")
    ax.axhline(0.0, color="0.5", lw=0.5)


def _near_null(result, fraction: float):
    """``(command, null, span, near)``: the recorded valve command (V), the rig's null and span (V), and where the
    command is within ``fraction`` of the span of null (N,) bool (:func:`.locate.near_null`)."""
    rig = result.nominal_fit.rig
    u = result.nominal_fit.recording.valve_cmd_V
    null, span = valve_null_and_span(rig)
    return u, null, span, near_null(u, rig, fraction)


_PLOTS = {"holding": _plot_holding, "direction": _plot_direction, "position": _plot_position,
          "pressure difference": _plot_pressure_difference, "lag": _plot_lag, "command map": _plot_command_map,
          "relaxation": _plot_relaxation, "over time": _plot_over_time}


def plot_evidence(result: DiagnosisResult, k: int, path, kind: str | None = None) -> Path:
    """The evidence of finding ``k``: the signature before (nominal) and after (with the findings up to k),
    the plot its effect names (``Effect.evidence_plot``; ``kind``: another of
    :data:`~pneusim.model.effects.EVIDENCE_PLOTS` instead)."""
    plt = pyplot()
    eff = result.findings[k].effect
    rec = result.nominal_fit.recording
    t, x = rec.time_s, rec.position_m
    nom, fin = named_states(result.nominal_fit), named_states(result.final_fit)
    v = velocity_estimate(t, x)
    e_nom = v - velocity_estimate(t, np.nan_to_num(nom["position_m"]))
    e_fin = v - velocity_estimate(t, np.nan_to_num(fin["position_m"]))
    fig, ax = plt.subplots(figsize=(7, 4.2))
    if kind is None:
        kind = EFFECTS[eff].evidence_plot if eff in EFFECTS else "over time"     # ``other``: over time
    plot = _PLOTS[kind]
    plot(ax, result, v, x, e_nom, e_fin, nom, fin)
    ax.legend(fontsize=8)
    fig.suptitle(f"{k + 1}. {eff}", fontsize=10)
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)
