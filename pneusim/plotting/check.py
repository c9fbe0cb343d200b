"""The figure standard as a check: what a finished figure must have before it is shown or saved.

:func:`figure_problems` lists, in one sentence each, what a figure lacks:

* a title: the figure's own (``suptitle``) or, for a figure of one panel, the panel's;
* a label on every axis that shows tick labels, with its unit in parentheses or brackets at the end
  (``"position (mm)"``, ``"fit (%)"``, ``"noise scale (-)"`` for a pure number) -- an axis of categories
  (tick labels that are not numbers) needs a label but no unit;
* legends that leave the data visible: no legend over more than :data:`.legend.LEGEND_MAX_SHARE` of any one
  series' points (measured on the drawn figure);
* nothing cut at the figure's edges: the title, panel titles, axis labels and legends inside the figure.

Test code gives every figure of a report to it through :func:`.figure.figure_hook`::

    with figure_hook(lambda fig, path: problems.extend(figure_problems(fig, path))):
        write_report(...)
"""

from __future__ import annotations

import re

from .legend import LEGEND_MAX_SHARE, covered_share, data_series

__all__ = ["figure_problems", "UNIT_AT_END"]

#: a unit at the end of an axis label: "(mm)", "(bar gauge)", "[V]", "(%)", "(-)"
UNIT_AT_END = re.compile(r"(\([^()]+\)|\[[^\[\]]+\])\s*$")
_NUMBER = re.compile(r"^[\s\u2212+\-]*[0-9.,]+([eE][\u2212+\-]?\d+)?\s*%?$|^\$.*\$$|^$")


def _numeric_ticks(labels) -> bool:
    texts = [t.get_text() for t in labels if t.get_visible()]
    return all(_NUMBER.match(t) for t in texts)


def _shows_ticks(labels) -> bool:
    return any(t.get_visible() and t.get_text().strip() for t in labels)


def _has_data(ax) -> bool:
    return bool(ax.get_lines() or ax.collections or ax.patches or ax.images or ax.containers)


def _axis_problems(ax, name: str, where: str) -> list[str]:
    labels = ax.get_xticklabels() if name == "x" else ax.get_yticklabels()
    if not _shows_ticks(labels):
        return []
    text = (ax.get_xlabel() if name == "x" else ax.get_ylabel()).strip()
    if not text:
        return [f"{where}: the {name} axis has tick labels but no label"]
    if _numeric_ticks(labels) and not UNIT_AT_END.search(text):
        return [f"{where}: the {name} axis label {text!r} gives no unit in parentheses at its end"]
    return []


def _title(fig) -> str:
    text = fig.get_suptitle().strip() if hasattr(fig, "get_suptitle") else ""
    if text:
        return text
    panels = [ax for ax in fig.axes if ax.get_visible() and _has_data(ax)]
    if len(panels) == 1:
        return panels[0].get_title().strip()
    return ""


def _cut_at_edges(fig, renderer, head: str) -> list[str]:
    """Texts and legends that reach beyond the figure's edges (by more than a pixel)."""
    box = fig.bbox
    items = [("the title", fig._suptitle)] if fig.get_suptitle() else []
    for ax in fig.axes:
        if ax.get_visible():
            items += [(f"the title {ax.get_title()!r}", ax.title), (f"the x label {ax.get_xlabel()!r}", ax.xaxis.label),
                      (f"the y label {ax.get_ylabel()!r}", ax.yaxis.label)]
            if ax.get_legend() is not None:
                items.append(("a legend", ax.get_legend()))
    items += [("a figure legend", leg) for leg in fig.legends]
    out = []
    for what, artist in items:
        if not artist.get_visible() or (hasattr(artist, "get_text") and not artist.get_text()):
            continue
        e = artist.get_window_extent(renderer)
        if e.x0 < box.x0 - 1 or e.x1 > box.x1 + 1 or e.y0 < box.y0 - 1 or e.y1 > box.y1 + 1:
            out.append(f"{head}: {what} reaches beyond the figure's edge")
    return out


def figure_problems(fig, name=None, max_legend_share: float = LEGEND_MAX_SHARE) -> list[str]:
    """What ``fig`` lacks of the standard, one sentence each (empty: it passes).  ``name`` (a file name or
    a caption) starts every sentence.  Draws the figure (without rendering) to measure the legends."""
    fig.draw_without_rendering()
    renderer = fig.canvas.get_renderer()
    head = str(name) if name is not None else (fig.get_suptitle() or "figure")
    problems = [] if _title(fig) else [f"{head}: no title (suptitle, or the title of its one panel)"]
    problems += _cut_at_edges(fig, renderer, head)
    for i, ax in enumerate(fig.axes):
        if not ax.get_visible() or not ax.axison:
            continue
        where = f"{head}, panel {i + 1}" + (f" ({ax.get_title()!r})" if ax.get_title() else "")
        problems += _axis_problems(ax, "x", where) + _axis_problems(ax, "y", where)
        legends = [ax.get_legend()] if ax.get_legend() is not None else []
        legends += [leg for leg in fig.legends]
        series = data_series(ax)
        for legend in legends:
            if not legend.get_visible():
                continue
            for label, share in covered_share(series, legend.get_window_extent(renderer)):
                if share > max_legend_share:
                    problems.append(f"{where}: the legend covers {100 * share:.0f} % of the points of "
                                    f"{label!r} (at most {100 * max_legend_share:g} %)")
    return problems
