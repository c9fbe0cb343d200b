"""Panels of the standard: measured against models with the error below and a zoom beside, ranges that
show the differences, and points off the range marked at its edge.

:func:`compare_figure` is the figure of every "which model follows the measurement" question: on top the
measured signal (black) and each model (its family's colour, fit % in the legend) over the whole
record; below, each model's error, where curves that overlap at full scale come apart; on the right the
same two panels zoomed on the window where the models miss most (shaded on the left).  The legend sits
under the panels, so it covers nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .figure import LEGEND_SIZE, PANEL_TITLE_SIZE, new_figure
from .legend import keep_in_place
from .style import COLOURS, fit_label, model_styles

__all__ = ["Curve", "Signal", "compare_figure", "zoom_window", "robust_range", "mark_clipped", "padded_range",
           "fit_range"]

#: the zoom window's length as a share of the record
ZOOM_SHARE = 0.08
#: a model whose error's 99th percentile is this many times the median model's leaves the error panel's range
#: (marked) instead of squashing every other model's error to a line
ERROR_OUTLIER_RATIO = 4.0


#: on a fit % axis, the share of values (lowest first) that may fall below the range: the worst outliers
OUTLIER_SHARE = 0.1
#: ... and how far below the rest the range reaches, in spans of the rest
CLIP_SPANS = 1.0


@dataclass
class Curve:
    """A model's output to draw beside the measurement: its name, values (same length as the time), fit % for
    the legend, identifier kind (for its colour), and an optional colour and line style of its own."""
    name: str
    values: np.ndarray
    fit_percent: float | None = None
    kind: str | None = None
    color: str | None = None
    ls: str | None = None


def padded_range(values, pad: float = 0.08):
    """``(low, high)`` around the finite ``values`` with ``pad`` of their span either side."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return -1.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    span = hi - lo or max(abs(hi), 1.0) * 0.1
    return lo - pad * span, hi + pad * span


def fit_range(values, top: float = 100.0):
    """``(low, high)`` of a fit % axis that shows the differences between the models that fit: the bulk of the
    values (all but the lowest :data:`OUTLIER_SHARE`) and :data:`CLIP_SPANS` times its span below it; lower
    values are clipped (mark them with :func:`mark_clipped`)."""
    v = np.sort(np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=float))
    if not v.size:
        return 0.0, top
    bulk_low = v[min(int(OUTLIER_SHARE * v.size), v.size - 1)]
    span = max(v[-1] - bulk_low, 1.0)
    low = max(v[0], bulk_low - CLIP_SPANS * span) - 0.1 * span
    high = min(v[-1] + 0.25 * span, top + 0.02 * span)
    return float(low), float(max(high, low + 1.0))


def robust_range(groups, ratio: float = ERROR_OUTLIER_RATIO, pad: float = 0.1):
    """``(low, high)`` holding every group of values (e.g. one model's errors) but those whose 99th
    percentile of magnitude is more than ``ratio`` times the median group's (those are clipped)."""
    sizes = [float(np.nanpercentile(np.abs(g), 99)) for g in groups if np.isfinite(g).any()]
    if not sizes:
        return -1.0, 1.0
    typical = float(np.median(sizes)) or max(sizes) or 1.0
    kept = [g for g, s in zip(groups, sizes) if s <= ratio * typical]
    return padded_range(np.concatenate([np.ravel(g) for g in kept]), pad)


def mark_clipped(ax, x, y, low: float, high: float, color, label_all: bool = True) -> int:
    """Draw the points of ``(x, y)`` outside ``[low, high]`` as open triangles on the edge they left by;
    returns how many there were.  Call after the axis range is final."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    below, above = y < low, y > high
    span = high - low
    for mask, edge, marker in ((below, low + 0.02 * span, "v"), (above, high - 0.02 * span, "^")):
        if mask.any():
            ax.plot(x[mask], np.full(mask.sum(), edge), marker, mfc="none", mec=color, ms=6, ls="none",
                    label="_clipped")
    return int(below.sum() + above.sum())


def zoom_window(t, errors, share: float = ZOOM_SHARE):
    """``(t0, t1)``: the window of ``share`` of the record where the models' summed square error is largest
    (where they differ from the measurement most)."""
    t = np.asarray(t, dtype=float)
    n = len(t)
    width = max(int(share * n), min(n, 20))
    if not errors or width >= n:
        return float(t[0]), float(t[-1])
    energy = np.zeros(n)
    for e in errors:
        e = np.nan_to_num(np.asarray(e, dtype=float), nan=0.0)
        energy += e ** 2 / (np.mean(e ** 2) or 1.0)
    window = np.convolve(energy, np.ones(width), mode="valid")
    start = int(np.argmax(window))
    return float(t[start]), float(t[start + width - 1])


@dataclass
class Signal:
    """One measured signal of a comparison and the models' outputs for it: a row pair of
    :func:`compare_figure` (the signal, then its errors).  ``ylabel`` is the quantity with its unit
    (``"position (mm)"``), ``unit`` the unit alone (for the error axis), ``title`` an optional title of the
    signal's panel."""
    measured: np.ndarray
    curves: list
    ylabel: str
    unit: str
    measured_label: str = "measured"
    title: str | None = None


def _draw_signal(ax: dict, t, sig: Signal, window, zoom: bool, error_panel: bool, legend: bool) -> None:
    """One signal's panels: measured and models (full and zoomed), their errors."""
    y = np.asarray(sig.measured, dtype=float)
    styles = model_styles([c.name for c in sig.curves], [c.kind for c in sig.curves])
    errors = [y - np.asarray(c.values, dtype=float) for c in sig.curves]
    for key in ("signal", "zoom_signal"):
        if key not in ax:
            continue
        a = ax[key]
        a.plot(t, y, color=COLOURS["measured"], lw=1.3, label=sig.measured_label if legend else "_", zorder=3)
        for c in sig.curves:
            st = styles[c.name]
            a.plot(t, c.values, color=c.color or st["color"], ls=c.ls or st["ls"], lw=0.9,
                   label=fit_label(c.name, c.fit_percent) if legend else "_", zorder=4)
        a.set_ylabel(sig.ylabel)
    if sig.title:
        ax["signal"].set_title(sig.title, fontsize=PANEL_TITLE_SIZE)
    values = [y] + [np.asarray(c.values, dtype=float) for c in sig.curves]
    ax["signal"].set_ylim(*(padded_range(np.concatenate(values), 0.05) if len(sig.curves) <= 1
                            else padded_range(y, 0.15)))
    for key in ("error", "zoom_error"):
        if key not in ax:
            continue
        a = ax[key]
        a.axhline(0.0, color=COLOURS["reference"], lw=0.6)
        for c, e in zip(sig.curves, errors):
            st = styles[c.name]
            a.plot(t, e, color=c.color or st["color"], ls=c.ls or st["ls"], lw=0.7, label="_")
        a.set_ylabel(f"error ({sig.unit})")
    if error_panel:
        ax["error"].set_ylim(*robust_range(errors))
    if zoom:
        mask = (t >= window[0]) & (t <= window[1])
        ax["zoom_signal"].set_xlim(*window)
        ax["zoom_signal"].set_ylim(*padded_range(np.concatenate([v[mask] for v in values]), 0.1))
        if error_panel:
            ax["zoom_error"].set_ylim(*robust_range([e[mask] for e in errors]))
        for key in ("signal", "error"):
            if key in ax:
                ax[key].axvspan(*window, color=COLOURS["window"], alpha=0.5, lw=0, zorder=0)


def compare_figure(t, measured=None, curves: list[Curve] | None = None, *, title: str, ylabel: str | None = None,
                   unit: str | None = None, measured_label: str = "measured", zoom: bool = True,
                   split_s: float | None = None, size=None, error_panel: bool = True, signals: list | None = None,
                   window=None):
    """Measured signal and model curves (top), their errors (below), the same zoomed on the window where
    the models miss most (right); the legend under the panels.  Returns ``(figure, axes)``: ``axes`` a
    dict ``"signal", "error"`` (and, zoomed, ``"zoom_signal", "zoom_error"``) -- or, for several
    ``signals``, a list of such dicts, one per signal.

    Parameters
    ----------
    t : array, shape (n,)
        Time, s.
    measured : array, shape (n,)
        The measured signal, in ``unit`` (or give ``signals``).
    curves : list of Curve
        The models' outputs, same length and unit.
    ylabel : str
        The quantity with its unit, e.g. ``"position (mm)"``.
    signals : list of Signal, optional
        Several signals (e.g. position and both chamber pressures), one row pair each, instead of
        ``measured``, ``curves``, ``ylabel`` and ``unit``.
    split_s : float, optional
        Where validation starts (a dotted line).
    window : (float, float), optional
        The zoom window, s (default: where the first signal's models miss most, :func:`zoom_window`).
    """
    t = np.asarray(t, dtype=float)
    one = signals is None
    if one:
        signals = [Signal(measured, list(curves), ylabel, unit, measured_label)]
    rows_each = 2 if error_panel else 1
    cols = 2 if zoom else 1
    size = size or (11.0, 5.6 if one else 2.6 * rows_each * len(signals) + 0.8)
    fig, axs = new_figure(rows_each * len(signals), cols, title=title, size=size, squeeze=False, sharex="col",
                          gridspec_kw={"width_ratios": [3, 1] if zoom else [1],
                                       "height_ratios": ([3, 2] if error_panel else [1]) * len(signals)})
    first = signals[0]
    if window is None:
        window = zoom_window(t, [np.asarray(first.measured, dtype=float) - np.asarray(c.values, dtype=float)
                                 for c in first.curves])
    panels = []
    for k, sig in enumerate(signals):
        r = rows_each * k
        ax = {"signal": axs[r, 0]}
        if error_panel:
            ax["error"] = axs[r + 1, 0]
        if zoom:
            ax["zoom_signal"] = axs[r, 1]
            if error_panel:
                ax["zoom_error"] = axs[r + 1, 1]
        _draw_signal(ax, t, sig, window, zoom, error_panel, legend=k == 0)
        if split_s is not None:
            for key in ("signal", "error"):
                if key in ax:
                    ax[key].axvline(split_s, color=COLOURS["reference"], ls=":", lw=1.0)
        panels.append(ax)
    for a in axs[-1, :]:
        a.set_xlabel("time (s)")
    if zoom:
        panels[0]["zoom_signal"].set_title(f"zoom: {window[0]:.2f}-{window[1]:.2f} s", fontsize=PANEL_TITLE_SIZE)
    handles, labels = panels[0]["signal"].get_legend_handles_labels()
    if split_s is not None:
        from matplotlib.lines import Line2D

        handles.append(Line2D([], [], color=COLOURS["reference"], ls=":", lw=1.0))
        labels.append(f"validation from {split_s:.1f} s")
    keep_in_place(fig.legend(handles, labels, loc="outside lower center", ncol=min(len(labels), 4),
                             fontsize=LEGEND_SIZE, frameon=False))
    return fig, (panels[0] if one else panels)
