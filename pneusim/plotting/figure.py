"""Making, finishing and saving a figure of the standard: one place every figure goes through.

:func:`new_figure` makes the figure (matplotlib on the Agg backend, imported on first use: it takes about
a second and only drawing needs it; constrained layout, so that labels and legends outside the axes get
their room).  :func:`save_figure` (reports) and :func:`show_figure` (notebooks) finish it: the legends are
placed where they cover no data (:func:`.legend.place_legends`), the hooks of :func:`figure_hook` see the
finished figure (a test checks every figure there), then it is written (and closed) or shown.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from ..outputs import savefig_atomic

__all__ = ["pyplot", "new_figure", "finish_figure", "save_figure", "show_figure", "figure_hook", "DPI",
           "TITLE_SIZE", "PANEL_TITLE_SIZE", "LEGEND_SIZE"]

#: resolution of report figures, dots per inch
DPI = 110
#: font sizes (points): the figure's title, a panel's title, legend entries
TITLE_SIZE, PANEL_TITLE_SIZE, LEGEND_SIZE = 11, 9, 8
#: the share of the figure's width a line of the title may take
TITLE_ROOM = 0.9

_HOOKS: list = []


def pyplot():
    """``matplotlib.pyplot``, imported on first use; on the Agg backend (files only) unless a backend is
    already chosen (a notebook's inline backend stays)."""
    import os
    import sys

    if "matplotlib.pyplot" not in sys.modules and "inline" not in os.environ.get("MPLBACKEND", ""):
        import matplotlib

        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def new_figure(nrows: int = 1, ncols: int = 1, *, title: str, size=(9.0, 4.0), **subplots):
    """``(figure, axes)`` as ``plt.subplots`` gives them, with constrained layout and the figure's ``title``
    (a sentence that states what the figure shows)."""
    plt = pyplot()
    fig, axes = plt.subplots(nrows, ncols, figsize=size, layout="constrained", **subplots)
    fig.suptitle(title, fontsize=TITLE_SIZE)
    return fig, axes


@contextlib.contextmanager
def figure_hook(hook):
    """Call ``hook(figure, path)`` for every figure finished inside the ``with`` block (``path`` None for a
    figure shown rather than saved): a test checks every figure a report or notebook makes this way."""
    _HOOKS.append(hook)
    try:
        yield hook
    finally:
        _HOOKS.remove(hook)


def _wrap_title(fig) -> None:
    """Break the figure's title into lines that fit its width (a long title would be cut at the edges); the
    lines keep a margin, as text drawn at another resolution (``savefig(dpi=...)``) is not exactly as wide."""
    import textwrap

    title = fig.get_suptitle()
    if not title:
        return
    text = " ".join(title.split())
    room = TITLE_ROOM * fig.bbox.width
    renderer = fig.canvas.get_renderer()
    chars = len(text)
    while chars > 20:
        fig._suptitle.set_text(textwrap.fill(text, chars) if chars < len(text) else text)
        if fig._suptitle.get_window_extent(renderer).width <= room:
            return
        chars = int(chars * 0.9)


def finish_figure(fig):
    """Apply the standard's last step to ``fig`` (a title broken into lines that fit, legends placed where they
    cover no data; a layout for a figure made without one); returns ``fig``."""
    from .legend import place_legends

    if fig.get_layout_engine() is None:
        # constrained layout cannot take over colour bars made without it; tight layout can
        colour_bars = any(hasattr(ax, "_colorbar") for ax in fig.axes)
        fig.set_layout_engine("tight" if colour_bars else "constrained")
    _wrap_title(fig)
    place_legends(fig)
    return fig


def save_figure(fig, path, dpi: int = DPI) -> Path:
    """Finish ``fig``, write it to ``path`` (PNG, SVG or PDF by the suffix; atomically: a crash leaves the
    previous file or none, never a truncated one) and close it; returns the path."""
    plt = pyplot()
    path = Path(path)
    try:
        finish_figure(fig)
        for hook in list(_HOOKS):
            hook(fig, path)
        savefig_atomic(fig, path, dpi=dpi)
    finally:
        plt.close(fig)
    return path


def show_figure(fig=None):
    """Finish ``fig`` (default: the current figure) and show it (in a notebook: inline, below the cell)."""
    plt = pyplot()
    fig = fig if fig is not None else plt.gcf()
    finish_figure(fig)
    for hook in list(_HOOKS):
        hook(fig, None)
    plt.show()
