"""Summary plots of a sweep table: each metric against each varied parameter, one series per identifier."""

from __future__ import annotations

import re
from pathlib import Path

from .figures import pyplot

__all__ = ["summary_plots"]


def summary_plots(table: list[dict], varied: list[str], out_dir, metric: str = "fit_percent") -> list[Path]:
    """One PNG per numeric varied key (``summary-KEY.png``): ``metric`` against the key, per identifier reading.

    Non-numeric keys (e.g. model orders) are drawn as categories.  Failed runs are left out.
    """
    plt = pyplot()
    out, paths = Path(out_dir), []
    ok = [r for r in table if r.get("status") == "ok" and r.get(metric) is not None]
    for key in varied:
        series = {}
        for r in ok:
            series.setdefault(f"{r['identifier']} {r['reading']}".strip(), []).append((r.get(key), r[metric]))
        if not series:
            continue
        fig, ax = plt.subplots(figsize=(7, 4))
        values = sorted({str(x) for s in series.values() for x, _ in s})
        numeric = all(isinstance(x, (int, float)) for s in series.values() for x, _ in s)
        for label, pts in series.items():
            xs = [x if numeric else values.index(str(x)) for x, _ in pts]
            ax.plot(xs, [m for _, m in pts], "o", ms=4, alpha=0.7, label=label)
        if not numeric:
            ax.set_xticks(range(len(values)), values, rotation=30, fontsize=7)
        if metric == "fit_percent":
            lowest = min(m for s in series.values() for _, m in s)
            ax.set_ylim(max(lowest, -100.0) - 5.0, 105.0)     # fits below -100 % are off the chart
            hidden = sum(m < -105.0 for s in series.values() for _, m in s)
            if hidden:
                ax.set_title(f"{hidden} point(s) below -105 % not shown", fontsize=8)
        ax.set_xlabel(key)
        ax.set_ylabel(metric)
        ax.legend(fontsize=6)
        fig.tight_layout()
        path = out / f"summary-{re.sub(r'[^A-Za-z0-9_.-]+', '_', key)}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths
