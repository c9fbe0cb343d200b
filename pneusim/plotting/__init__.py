"""The figure standard every figure of pneusim goes through (reports, ``pneusim plot``, notebooks).

* :mod:`.style` -- one colour per role and model family (:data:`COLOURS`, :func:`colour_for`), engineering
  units (:func:`mm`, :func:`bar_gauge` ...), legend entries with the fit (:func:`fit_label`);
* :mod:`.figure` -- :func:`new_figure`, and :func:`save_figure` / :func:`show_figure`, the one place a
  figure is finished (legends placed where they cover no data) and written or shown;
* :mod:`.panels` -- :func:`compare_figure` (measured and models, the error below, a zoom beside), ranges
  that show the differences and mark what they clip;
* :mod:`.legend` -- what a legend covers, measured, and where it goes;
* :mod:`.check` -- :func:`figure_problems`, the standard as a check (title, labelled axes with units,
  legends off the data), for tests through :func:`figure_hook`;
* :mod:`.page` -- a report page as blocks, rendered to Markdown and to self-contained HTML.

matplotlib is imported when the first figure is made, not with this package.
"""

from .check import figure_problems
from .figure import DPI, figure_hook, finish_figure, new_figure, pyplot, save_figure, show_figure
from .legend import LEGEND_MAX_SHARE, keep_in_place
from .page import render_html, render_markdown, write_page
from .panels import Curve, Signal, compare_figure, fit_range, mark_clipped, padded_range, robust_range, zoom_window
from .style import (COLOURS, STANDARD_ATMOSPHERE_PA, bar_abs, bar_gauge, colour_for, family_of, fit_label, mm,
                    mm_per_s, model_styles, ms, parameter_axis)

__all__ = ["COLOURS", "STANDARD_ATMOSPHERE_PA", "bar_abs", "bar_gauge", "colour_for", "family_of", "fit_label", "mm",
           "mm_per_s", "model_styles", "ms", "parameter_axis", "DPI", "figure_hook", "finish_figure", "new_figure",
           "pyplot", "save_figure", "show_figure", "LEGEND_MAX_SHARE", "keep_in_place", "figure_problems",
           "Curve", "Signal", "compare_figure", "fit_range", "mark_clipped", "padded_range", "robust_range",
           "zoom_window",
           "render_html", "render_markdown", "write_page"]
