"""Summary plots of a sweep table: each metric against each varied parameter, one series per identifier.

In the figure standard (:mod:`pneusim.plotting`): the varied key in the unit a reader uses (supply pressure
in bar gauge, lengths in mm ...), a vertical range that shows the differences between the models that fit
(points far below are clipped and marked on the lower edge, with their count), the papers' published models
in a panel of their own so that their large misses do not squash the others, and the median of each series
in the legend.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..plotting import family_of, fit_range, mark_clipped, model_styles, new_figure, parameter_axis, save_figure

__all__ = ["summary_plots"]

def _series(rows, key, metric):
    series = {}
    for r in rows:
        label = r["identifier"] if r.get("n_readings", 1) == 1 else f"{r['identifier']}, {r['reading']}".strip(", ")
        series.setdefault(label, []).append((r.get(key), r[metric]))
    return series


def _is_published(label: str) -> bool:
    return family_of(label) == "published"


def _panel(ax, series, numeric, values, convert, metric, styles):
    """One panel of series; returns the number of points clipped off its range."""
    xs_all = sorted({float(convert(x)) for pts in series.values() for x, _ in pts}) if numeric else values
    gap = float(np.min(np.diff(xs_all))) if numeric and len(xs_all) > 1 else 1.0
    grid = numeric and len(xs_all) <= 12
    dodge = 0.25 * gap / max(len(series), 1) if grid else 0.0
    ys = [m for pts in series.values() for _, m in pts]
    low, high = fit_range(ys) if metric == "fit_percent" else (None, None)
    clipped = 0
    for i, (label, pts) in enumerate(series.items()):
        x = np.array([convert(p[0]) if numeric else values.index(str(p[0])) for p in pts], dtype=float)
        x = x + (i - (len(series) - 1) / 2) * dodge
        y = np.array([p[1] for p in pts], dtype=float)
        st = styles[label]
        median = float(np.nanmedian(y))
        unit = " %" if metric == "fit_percent" else ""
        ax.plot(x, y, st["marker"], ms=4, alpha=0.75, color=st["color"], ls="none",
                label=f"{label} (median {median:.1f}{unit})")
        if grid:
            xm = sorted(set(x.tolist()))
            ym = [np.nanmedian(y[x == v]) for v in xm]
            ax.plot(xm, ym, lw=0.8, color=st["color"], ls=st["ls"], alpha=0.6, label="_median")
        if low is not None:
            ax.set_ylim(low, high)
            clipped += mark_clipped(ax, x, y, low, high, st["color"])
    return clipped, (low, ys)


def summary_plots(table: list[dict], varied: list[str], out_dir, metric: str = "fit_percent") -> list[Path]:
    """One PNG per varied key (``summary-KEY.png``): ``metric`` against the key, per identifier reading.

    Non-numeric keys (e.g. model orders) are drawn as categories.  Failed runs are left out.
    """
    out, paths = Path(out_dir), []
    ok = [r for r in table if r.get("status") == "ok" and r.get(metric) is not None]
    readings = {}
    for r in ok:
        readings.setdefault(r["identifier"], set()).add(r.get("reading", ""))
    ok = [{**r, "n_readings": len(readings[r["identifier"]])} for r in ok]
    metric_label = {"fit_percent": "validation fit (%)", "square_error": "square error (output unit^2)",
                    "mse": "mean square error (output unit^2)"}.get(metric, f"{metric.replace('_', ' ')} (-)")
    for key in varied:
        series = _series(ok, key, metric)
        if not series:
            continue
        numeric = all(isinstance(x, (int, float)) for s in series.values() for x, _ in s)
        values = sorted({str(x) for s in series.values() for x, _ in s})
        label, convert = parameter_axis(key) if numeric else (f"{key.split('.')[-1].replace('_', ' ')}", None)
        convert = convert or (lambda x: x)
        main = {k: v for k, v in series.items() if not _is_published(k)}
        published = {k: v for k, v in series.items() if _is_published(k)}
        panels = [p for p in (main, published) if p]
        runs = len({r["run_id"] for r in ok})
        quantity = label.rsplit(" (", 1)[0]
        fig, axes = new_figure(len(panels), 1, size=(9, 4.2 + 2.0 * (len(panels) - 1)), squeeze=False, sharex=True,
                               gridspec_kw={"height_ratios": [3, 1.6][:len(panels)]},
                               title=f"How each model's {metric_label.rsplit(' (', 1)[0]} changes with the {quantity} "
                                     f"({runs} runs)")
        styles = model_styles(list(series))
        for ax, group in zip(axes[:, 0], panels):
            clipped, (low, ys) = _panel(ax, group, numeric, values, convert, metric, styles)
            ax.set_ylabel(metric_label)
            notes = ["the papers' published models under each reading, on a range of their own"] \
                if group is published else []
            if clipped:
                notes.append(f"{clipped} point(s) below the range, marked by open triangles on the lower edge "
                             f"(lowest {min(ys):.3g})")
            if notes:
                ax.set_title("; ".join(notes), fontsize=8)
            ax.legend(fontsize=7)
            ax.grid(alpha=0.3)
        bottom = axes[-1, 0]
        if not numeric:
            bottom.set_xticks(range(len(values)), values, rotation=30, fontsize=7)
        bottom.set_xlabel(label)
        path = out / f"summary-{re.sub(r'[^A-Za-z0-9_.-]+', '_', key)}.png"
        paths.append(save_figure(fig, path, dpi=100))
    return paths
