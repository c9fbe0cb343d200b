"""The figure standard's parts (pneusim.plotting): colours by family, engineering units, legends placed off
the data, ranges that show differences, the compare figure, the report page."""

import numpy as np
import pytest

from pneusim.plotting import (COLOURS, Curve, Signal, bar_gauge, colour_for, compare_figure, family_of,
                              figure_hook, figure_problems, fit_range, mark_clipped, model_styles, new_figure,
                              parameter_axis, pyplot, render_html, render_markdown, save_figure, write_page,
                              zoom_window)
from pneusim.plotting.legend import covered_share, data_series


@pytest.mark.parametrize("name, kind, family", [
    ("ARX [3 3 1]", None, "arx"), ("ARMAX [3 3 2 1]", None, "armax"), ("state space n=3", None, "ss"),
    ("TF 3 poles 2 zeros", None, "tf"), ("General Transfer Function", None, "tf"), ("BJ", None, "bj"),
    ("OE [2 2 1]", None, "oe"), ("RLS ARMA order 4", None, "rls"), ("published eq. 9 (3rd order)", None, "published"),
    ("physical, told 2 bar", None, "physical"), ("nominal model", None, "nominal"),
    ("anything", "physical_fit", "physical"), ("State Space", "ss", "ss"),
    ("measured (simulated rig)", None, "measured"),
])
def test_every_family_has_its_colour(name, kind, family):
    assert family_of(name, kind) == family
    assert colour_for(name, kind) is not None


def test_rls_orders_and_repeated_families_are_told_apart():
    assert len({colour_for(f"order {k}", "rls") for k in (3, 4, 5)}) == 3
    styles = model_styles(["ARX", "ARX [4 4 1]", "ARMAX"])
    assert styles["ARX"]["color"] == COLOURS["arx"] and styles["ARMAX"]["color"] == COLOURS["armax"]
    assert styles["ARX [4 4 1]"]["color"] != COLOURS["arx"] and styles["ARX [4 4 1]"]["ls"] == "--"


def test_engineering_units_of_the_varied_keys():
    label, convert = parameter_axis("rig.overrides.supply_Pa")
    assert label == "supply pressure (bar gauge)" and convert(601325.0) == pytest.approx(5.0)
    assert parameter_axis("rig.overrides.stroke_m")[0] == "stroke (mm)"
    assert parameter_axis("experiment.sample_time_s")[0] == "sample time (ms)"
    assert bar_gauge(301325.0) == pytest.approx(2.0)


def test_a_legend_goes_where_it_covers_no_data(tmp_path):
    """Data filling the left half and the top: the legend goes where it covers nothing; data everywhere:
    outside, to the right."""
    t = np.linspace(0.0, 1.0, 400)
    fig, ax = new_figure(title="placement", size=(6, 4))
    ax.plot(t * 0.5, np.sin(20 * t), label="left half")
    ax.plot(t, np.full_like(t, 0.95), label="top")
    ax.set_ylim(-1.05, 1.05)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position (mm)")
    ax.legend(loc="upper left")
    measured = {}

    def measure(f, path):
        renderer = f.canvas.get_renderer()
        a = f.axes[0]
        extent = a.get_legend().get_window_extent(renderer)
        measured[path.name] = (max(s for _, s in covered_share(data_series(a), extent)), extent.x0,
                               a.get_window_extent(renderer).x1)

    with figure_hook(measure):
        save_figure(fig, tmp_path / "a.png")
        fig, ax = new_figure(title="everywhere", size=(6, 4))
        for k in range(8):
            ax.plot(t, np.sin(20 * t + k), label=f"curve {k}")
        ax.legend()
        save_figure(fig, tmp_path / "b.png")
    assert measured["a.png"][0] == 0.0
    assert measured["b.png"][1] >= measured["b.png"][2]          # the legend's left edge right of the axes


def test_fit_range_shows_the_good_models_and_clips_the_worst():
    values = [95.1, 95.9, 96.2, 94.8, 95.5, 95.0, 96.0, 95.7, 95.3, -420.0]
    low, high = fit_range(values)
    assert 85.0 < low < 94.8 and 96.2 < high <= 100.5
    fig, ax = new_figure(title="clipped")
    ax.set_ylim(low, high)
    assert mark_clipped(ax, np.arange(len(values)), values, low, high, "k") == 1
    pyplot().close(fig)


def test_zoom_window_is_where_the_models_miss_most():
    t = np.arange(1000) * 0.01
    error = np.where((t > 6.0) & (t < 6.5), 1.0, 0.01)
    t0, t1 = zoom_window(t, [error])
    assert 5.7 <= t0 <= 6.2 and 6.3 <= t1 <= 6.8


@pytest.mark.slow
def test_compare_figure_of_several_signals_meets_the_standard(tmp_path):
    t = np.linspace(0.0, 10.0, 1000)
    y = np.sin(t)
    signals = [Signal(y, [Curve("physical model", y + 0.01, 99.0, "physical_fit")], "position (mm)", "mm",
                      title="position"),
               Signal(2 * y, [Curve("physical model", 2 * y - 0.02, 98.0, "physical_fit")], "pressure A (bar gauge)",
                      "bar")]
    fig, axes = compare_figure(t, signals=signals, title="two signals", split_s=7.0)
    assert len(axes) == 2 and set(axes[0]) == {"signal", "error", "zoom_signal", "zoom_error"}
    assert figure_problems(fig) == []
    save_figure(fig, tmp_path / "c.png")
    assert (tmp_path / "c.png").stat().st_size > 10_000


def test_the_page_renders_both_ways_with_the_figure_inlined(tmp_path):
    fig, ax = new_figure(title="a figure")
    ax.plot([0, 1], [0, 1])
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position (mm)")
    save_figure(fig, tmp_path / "f.png")
    blocks = [("h", (1, "Title")), ("p", "Fit **99.87 %** of `position_m`."), ("ul", ["one", "two"]),
              ("table", (["signal", "fit (%)"], [["position", "99.87"], ["pressure A | B", "97.05"]])),
              ("fig", ("f.png", "the figure")), ("code", "pneusim fit run.csv")]
    md = render_markdown(blocks)
    assert "| pressure A \\| B | 97.05 |" in md and "![the figure](f.png)" in md
    page = render_html(blocks, "t", tmp_path)
    assert "<b>99.87 %</b>" in page and "<code>position_m</code>" in page and "data:image/png;base64," in page
    assert write_page(blocks, tmp_path, "t", html_name="index.html") == tmp_path / "index.html"
    assert (tmp_path / "report.md").read_text() == md
