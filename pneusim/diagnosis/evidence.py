"""Evidence a reader can see: each finding's plot is the signature that identifies it, drawn where it shows.

Every effect declares which plot that is (its ``evidence_plot``, one of
:data:`pneusim.model.effects.EVIDENCE_PLOTS`); :data:`PLOTS` draws each.  A plot compares the model
*without* the finding (the other findings in: the drop-one fit, or the nominal fit for a lone finding) with the
model *with* every finding, and the measurement where it is measured, so that what the finding explains is
what changes between the two curves:

* ``worst window`` -- position (and pressures) over the stretch where the model without it misses most;
* ``command map near null`` -- velocity against the command near null, binned at the command's own
  resolution: a dead band's flat spot, an offset's shifted zero crossing;
* ``creep while holding`` -- the stretch where the valve holds near null and the model without it drifts off
  most: position and pressures;
* ``residual by direction`` -- the velocity residual against the measured velocity: a step at zero;
* ``residual against pressure difference`` -- the velocity residual's size against ``|p_A - p_B|``;
* ``residual against position`` -- the position residual against the position: a spring's slope;
* ``command-residual lag`` -- the cross-correlation of command and residual increments against the lag, and
  the response to the largest command step;
* ``long moves`` -- the velocity over the longest stretch with the valve wide open.

Every figure goes through the figure standard (:func:`pneusim.plotting.save_figure`).
"""

from __future__ import annotations

import numpy as np

from ..plotting import COLOURS, mm, mm_per_s, new_figure, save_figure
from .locate import named_states, operating_conditions, velocity_estimate

__all__ = ["PLOTS", "Compared", "evidence_figure", "stretch"]


class Compared:
    """What an evidence plot compares: the recording, the states of the model without the finding and with
    every finding, their labels, and the rig."""

    def __init__(self, recording, rig, without, with_all, label_without: str, label_with: str):
        self.recording, self.rig = recording, rig
        self.without, self.with_all = named_states(without), named_states(with_all)
        self.labels = (label_without, label_with)
        self.t = recording.time_s
        self.v = velocity_estimate(self.t, recording.position_m)

    def models(self):
        """``[(states, label, colour, line style)]`` of the two models."""
        return [(self.without, self.labels[0], COLOURS["nominal"], "--"),
                (self.with_all, self.labels[1], COLOURS["improved"], "-")]


def stretch(mask: np.ndarray, energy: np.ndarray, least: int) -> tuple[int, int] | None:
    """The contiguous run of ``mask`` (at least ``least`` samples) with the largest sum of ``energy``;
    ``(start, stop)`` or None."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    runs = [(a, b) for a, b in zip(edges[::2], edges[1::2]) if b - a >= least]
    if not runs:
        return None
    return max(runs, key=lambda r: float(np.nansum(energy[r[0]:r[1]])))


def _error_energy(c: Compared) -> np.ndarray:
    e = c.recording.position_m - np.nan_to_num(c.without["position_m"])
    return e ** 2


def _signals(c: Compared):
    """``[(name, measured, scale, label)]``: position in mm, and the pressures in bar gauge when recorded."""
    rec = c.recording
    out = [("position_m", rec.position_m, mm, "position (mm)")]
    if rec.has_pressures:
        atm = float(c.rig.params.get("atmosphere_Pa", 101325.0))
        gauge = lambda p: (np.asarray(p) - atm) * 1e-5  # noqa: E731
        out += [("pressure_a_Pa", rec.pressure_a_Pa, gauge, "p_A (bar gauge)"),
                ("pressure_b_Pa", rec.pressure_b_Pa, gauge, "p_B (bar gauge)")]
    return out


def _over_time(c: Compared, a: int, b: int, title: str):
    """Measured and both models over samples ``a:b``, one panel per measured signal."""
    signals = _signals(c)
    fig, axes = new_figure(len(signals), 1, title=title, size=(9.0, 2.4 * len(signals) + 0.6), squeeze=False,
                           sharex=True)
    t = c.t[a:b]
    for ax, (name, y, scale, label) in zip(axes[:, 0], signals):
        ax.plot(t, scale(y[a:b]), color=COLOURS["measured"], lw=1.2, label="measured")
        for states, lab, colour, ls in c.models():
            ax.plot(t, scale(states[name][a:b]), color=colour, ls=ls, lw=1.0, label=lab)
        ax.set_ylabel(label)
    axes[0, 0].legend(fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    return fig


def _worst_window(c: Compared, effect: str):
    n = c.t.size
    width = max(20, min(n, n // 12))
    energy = np.convolve(_error_energy(c), np.ones(width), mode="valid")
    a = int(np.argmax(energy))
    return _over_time(c, a, a + width, f"{effect}: where the model without it misses most "
                                        f"({c.t[a]:.1f}-{c.t[a + width - 1]:.1f} s)")


def _binned(x, y, edges):
    """Means of ``y`` in the bins ``edges`` of ``x`` with at least three samples: ``(centres, means)``."""
    ok = np.isfinite(x) & np.isfinite(y)
    idx = np.digitize(x[ok], edges) - 1
    centres, means = [], []
    for k in range(len(edges) - 1):
        m = idx == k
        if m.sum() >= 3:
            centres.append(float(np.mean(x[ok][m])))
            means.append(float(np.mean(y[ok][m])))
    return np.array(centres), np.array(means)


def _resolution(u: np.ndarray) -> float:
    """The command's resolution, V: the smallest step between its distinct values (at least 1 mV)."""
    levels = np.unique(np.round(u, 6))
    steps = np.diff(levels)
    steps = steps[steps > 1e-6]
    return float(max(np.min(steps), 1e-3)) if steps.size else 1e-3


def _command_map(c: Compared, effect: str):
    u = c.recording.valve_cmd_V
    null = float(c.rig.params.get("valve_null_V", 5.0))
    rel = u - null
    half = float(np.clip(np.percentile(np.abs(rel), 60), 0.2, 1.5))
    step = max(_resolution(u), half / 40)
    edges = np.arange(-half, half + step, step)
    fig, ax = new_figure(title=f"{effect}: velocity against the valve command near null (bins of {step * 1e3:.0f} mV)",
                         size=(8.0, 4.2))
    x, y = _binned(rel, c.v, edges)
    ax.plot(x + null, mm_per_s(y), "o", ms=3, color=COLOURS["measured"], label="measured")
    for states, lab, colour, ls in c.models():
        x, y = _binned(rel, states["velocity_m_per_s"], edges)
        ax.plot(x + null, mm_per_s(y), ls=ls, marker=".", ms=3, color=colour, label=lab)
    ax.axvline(null, color=COLOURS["reference"], ls=":", lw=1.0)
    ax.axhline(0.0, color=COLOURS["reference"], lw=0.6)
    ax.set_xlabel("valve command (V)")
    ax.set_ylabel("piston velocity, binned mean (mm/s)")
    ax.legend(fontsize=8)
    return fig


def _creep(c: Compared, effect: str):
    masks = operating_conditions(c.recording, c.rig, c.v)
    holding = masks["holding still"] & masks["valve near null"]
    least = max(20, c.t.size // 200)
    run = stretch(holding, _error_energy(c), least) or stretch(masks["holding still"], _error_energy(c), least)
    if run is None:
        return _worst_window(c, effect)
    a, b = run
    pad = max(5, (b - a) // 10)
    a, b = max(0, a - pad), min(c.t.size, b + pad)
    return _over_time(c, a, b, f"{effect}: while the valve holds near null ({c.t[a]:.1f}-{c.t[b - 1]:.1f} s)")


def _residual_against(c: Compared, effect: str, x, xlabel: str, residual, ylabel: str, title: str, bins: int = 24):
    fig, ax = new_figure(title=f"{effect}: {title}", size=(8.0, 4.2))
    ok = np.isfinite(x)
    edges = np.linspace(np.nanpercentile(x[ok], 1), np.nanpercentile(x[ok], 99), bins + 1)
    for states, lab, colour, ls in c.models():
        cx, cy = _binned(x, residual(states), edges)
        ax.plot(cx, cy, ls=ls, marker="o", ms=3, color=colour, label=lab)
    ax.axhline(0.0, color=COLOURS["reference"], lw=0.6)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)
    return fig


def _direction(c: Compared, effect: str):
    moving = np.abs(c.v) > 0.01 * c.rig.stroke_m
    v = np.where(moving, mm_per_s(c.v), np.nan)
    return _residual_against(c, effect, v, "measured velocity (mm/s)",
                             lambda s: mm_per_s(c.v - s["velocity_m_per_s"]),
                             "velocity residual, binned mean (mm/s)", "the velocity residual against the direction "
                             "of motion (a step at zero: friction that differs each way)")


def _pressure_difference(c: Compared, effect: str):
    rec = c.recording
    if rec.has_pressures:
        dp, where = np.abs(rec.pressure_a_Pa - rec.pressure_b_Pa) * 1e-5, "measured"
    else:
        dp, where = np.abs(c.without["pressure_a_Pa"] - c.without["pressure_b_Pa"]) * 1e-5, "of the model"
    moving = np.abs(c.v) > 0.01 * c.rig.stroke_m
    return _residual_against(c, effect, np.where(moving, dp, np.nan), f"|p_A - p_B| {where} (bar)",
                             lambda s: mm_per_s(np.abs(c.v - s["velocity_m_per_s"])),
                             "|velocity residual|, binned mean (mm/s)",
                             "the velocity residual's size against the pressure across the seal")


def _position(c: Compared, effect: str):
    x = c.recording.position_m
    return _residual_against(c, effect, mm(x), "position (mm)", lambda s: mm(x - s["position_m"]),
                             "position residual, binned mean (mm)", "the position residual against the position "
                             "(a slope: a force that follows the position)")


def _lag(c: Compared, effect: str):
    rec = c.recording
    dt = float(c.t[1] - c.t[0])
    du = np.diff(rec.valve_cmd_V)
    lags = np.arange(0, max(3, min(int(round(0.2 / dt)), du.size // 4)))
    fig, axes = new_figure(1, 2, title=f"{effect}: the command-residual cross-correlation (left) and the response "
                                       "to the largest command step (right)", size=(10.0, 4.2))
    for states, lab, colour, ls in c.models():
        r = np.diff(rec.position_m - np.nan_to_num(states["position_m"]))
        cc = [np.corrcoef(du[:du.size - k], r[k:])[0, 1] if np.std(r[k:]) > 0 and np.std(du) > 0 else np.nan
              for k in lags]
        axes[0].plot(lags * dt * 1e3, cc, ls=ls, marker=".", ms=3, color=colour, label=lab)
    axes[0].axhline(0.0, color=COLOURS["reference"], lw=0.6)
    axes[0].set_xlabel("lag (ms)")
    axes[0].set_ylabel("correlation of increments (-)")
    axes[0].legend(fontsize=8)
    k = int(np.argmax(np.abs(du)))
    a, b = max(0, k - len(lags) // 4), min(c.t.size, k + 3 * len(lags))
    ms_ = (c.t[a:b] - c.t[k]) * 1e3
    axes[1].plot(ms_, mm(rec.position_m[a:b]), color=COLOURS["measured"], lw=1.2, label="measured")
    for states, lab, colour, ls in c.models():
        axes[1].plot(ms_, mm(states["position_m"][a:b]), color=colour, ls=ls, lw=1.0, label=lab)
    axes[1].set_xlabel(f"time after the step at {c.t[k]:.2f} s (ms)")
    axes[1].set_ylabel("position (mm)")
    return fig


def _long_moves(c: Compared, effect: str):
    masks = operating_conditions(c.recording, c.rig, c.v)
    run = stretch(masks["large opening"], _error_energy(c), max(10, c.t.size // 400))
    if run is None:
        return _worst_window(c, effect)
    a, b = run
    a, b = max(0, a - (b - a) // 4), min(c.t.size, b + (b - a) // 4)
    fig, ax = new_figure(title=f"{effect}: the piston's speed through the longest stretch with the valve wide open "
                               f"({c.t[a]:.1f}-{c.t[b - 1]:.1f} s)", size=(8.0, 4.2))
    ax.plot(c.t[a:b], mm_per_s(c.v[a:b]), color=COLOURS["measured"], lw=1.2, label="measured")
    for states, lab, colour, ls in c.models():
        ax.plot(c.t[a:b], mm_per_s(states["velocity_m_per_s"][a:b]), color=colour, ls=ls, lw=1.0, label=lab)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("piston velocity (mm/s)")
    ax.legend(fontsize=8)
    return fig


#: how each evidence plot of :data:`pneusim.model.effects.EVIDENCE_PLOTS` is drawn
PLOTS = {"worst window": _worst_window, "command map near null": _command_map, "creep while holding": _creep,
         "residual by direction": _direction, "residual against pressure difference": _pressure_difference,
         "residual against position": _position, "command-residual lag": _lag, "long moves": _long_moves}


def evidence_figure(kind: str, compared: Compared, effect: str, path):
    """Draw evidence plot ``kind`` for ``effect`` and save it to ``path`` through the figure standard."""
    fig = PLOTS[kind](compared, effect)
    return save_figure(fig, path)
