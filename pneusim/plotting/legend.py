"""Legends that do not cover data: the share of each series' points under a legend, measured, and a
placement that keeps it small.

A legend is placed in the corner (or side) of its axes where it covers the smallest share of any one
series' points; when every such place covers more than :data:`LEGEND_MAX_SHARE` of some series, it goes
outside the axes, to the right.  The share is counted per series (a legend over a whole short series
hides it even when the long ones are free), over the points inside the axes' view: the points of lines
drawn in data coordinates, the markers of scatter plots, and the bars of bar charts and histograms.
Reference lines drawn across the axes (``axhline``, ``axvline``) and shaded spans are not data.
"""

from __future__ import annotations

import weakref

import numpy as np

__all__ = ["LEGEND_MAX_SHARE", "LEGEND_PAD_PX", "PLACES", "data_series", "covered_share", "place_legends",
           "keep_in_place"]

#: the largest share of any one series' points a legend may cover (2 %: a corner legend over the tail of
#: a curve passes, a legend across a curve's middle does not)
LEGEND_MAX_SHARE = 0.02
#: where a legend may go inside its axes, in the order tried (the first of equal coverage wins)
#: a point this close to a legend's frame counts as covered, pixels (half a marker's width: a marker centred
#: just outside the frame is still partly under it)
LEGEND_PAD_PX = 4.0
PLACES = ("upper right", "upper left", "lower right", "lower left", "center right", "center left",
          "upper center", "lower center")

_FIXED: "weakref.WeakSet" = weakref.WeakSet()


def keep_in_place(legend):
    """Leave ``legend`` where its caller put it (:func:`place_legends` skips it); returns it."""
    _FIXED.add(legend)
    return legend


def _inside(points, box):
    return ((points[:, 0] >= box.x0) & (points[:, 0] <= box.x1) & (points[:, 1] >= box.y0)
            & (points[:, 1] <= box.y1))


def data_series(ax) -> list[tuple[str, str, np.ndarray]]:
    """Every data series of ``ax`` inside its view: ``(label, "points" | "boxes", array)`` with the display
    coordinates (pixels) of its points, shape (n, 2), or of its bars' corners ``x0, y0, x1, y1``, shape
    (n, 4), clipped to the axes."""
    from matplotlib.collections import PathCollection
    from matplotlib.container import BarContainer

    box = ax.get_window_extent()
    series = []
    for line in ax.get_lines():
        if not line.get_visible() or line.get_transform() is not ax.transData:
            continue
        xy = np.asarray(line.get_xydata(), dtype=float).reshape(-1, 2)
        xy = xy[np.isfinite(xy).all(axis=1)]
        if xy.size:
            pts = ax.transData.transform(xy)
            pts = pts[_inside(pts, box)]
            if len(pts):
                series.append((line.get_label(), "points", pts))
    for coll in ax.collections:
        if isinstance(coll, PathCollection) and coll.get_visible():
            offsets = np.asarray(coll.get_offsets(), dtype=float).reshape(-1, 2)
            offsets = offsets[np.isfinite(offsets).all(axis=1)]
            if offsets.size:
                pts = coll.get_offset_transform().transform(offsets)
                pts = pts[_inside(pts, box)]
                if len(pts):
                    series.append((coll.get_label(), "points", pts))
    for container in ax.containers:
        if isinstance(container, BarContainer):
            boxes = []
            for patch in container.patches:
                if not patch.get_visible():
                    continue
                e = patch.get_window_extent()
                x0, x1 = max(min(e.x0, e.x1), box.x0), min(max(e.x0, e.x1), box.x1)
                y0, y1 = max(min(e.y0, e.y1), box.y0), min(max(e.y0, e.y1), box.y1)
                if x1 > x0 and y1 >= y0:
                    boxes.append((x0, y0, x1, y1))
            if boxes:
                series.append((container.get_label(), "boxes", np.array(boxes)))
    return series


def covered_share(series, extent) -> list[tuple[str, float]]:
    """``[(label, share)]``: the share of each series' points (or bars) under the rectangle ``extent`` (a
    matplotlib ``Bbox`` in display coordinates), widened by :data:`LEGEND_PAD_PX`."""
    extent = extent.padded(LEGEND_PAD_PX)
    shares = []
    for label, kind, arr in series:
        if kind == "points":
            covered = _inside(arr, extent)
        else:
            covered = ((arr[:, 0] < extent.x1) & (arr[:, 2] > extent.x0) & (arr[:, 1] <= extent.y1)
                       & (arr[:, 3] >= extent.y0))
        shares.append((label, float(np.mean(covered))))
    return shares


def _worst(series, extent) -> float:
    return max((s for _, s in covered_share(series, extent)), default=0.0)


def _outside(legend, ax) -> None:
    legend.set_loc("upper left")
    legend.set_bbox_to_anchor((1.01, 1.0), transform=ax.transAxes)


def place_legends(fig, max_share: float = LEGEND_MAX_SHARE) -> None:
    """Put every axes legend of ``fig`` (but those given to :func:`keep_in_place`) where it covers the
    least data, or outside to the right when every place inside covers more than ``max_share`` of some
    series.  Runs the figure's layout first (a legend moved outside makes the layout run again)."""
    fig.draw_without_rendering()
    renderer = fig.canvas.get_renderer()
    placed_inside, moved_outside = [], False
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is None or legend in _FIXED or not legend.get_visible():
            continue
        series = data_series(ax)
        best, best_share = None, np.inf
        for place in PLACES:
            legend.set_loc(place)
            share = _worst(series, legend.get_window_extent(renderer))
            if share < best_share - 1e-12:
                best, best_share = place, share
            if share == 0.0:
                break
        if best_share <= max_share:
            legend.set_loc(best)
            placed_inside.append((ax, legend))
        else:
            _outside(legend, ax)
            moved_outside = True
    if moved_outside:
        # the layout made room for the legends outside; the axes moved, so look again at those inside
        fig.draw_without_rendering()
        renderer = fig.canvas.get_renderer()
        for ax, legend in placed_inside:
            if _worst(data_series(ax), legend.get_window_extent(renderer)) > max_share:
                _outside(legend, ax)
                fig.draw_without_rendering()
