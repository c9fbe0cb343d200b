"""Every figure the reports make meets the figure standard (:mod:`pneusim.plotting`): a title, a label with
its unit on every axis that shows numbers, no legend over more than 2 % of any series' points, nothing cut
at the figure's edges.

Each report writer runs on a small input inside :func:`checked_figures`, which checks every matplotlib
figure when it is saved (``Figure.savefig``, whatever module saves it) and before it is written;
:func:`assert_standard` then fails on any problem and on a PNG written without being checked.  To add a
report, run its writer inside ``checked_figures()`` and call ``assert_standard`` -- one line each.  The
notebooks' figures are checked in their kernels by ``tests/test_notebooks.py``, with the same checker.

Covered: the scenario reports (the tiny scenarios of ``tests/pneusim/scenario/data`` and both paper
scenarios shortened), the sweep's summary plots and an ablation's figure, the MRE report, the fit report
(and its self-contained page), ``pneusim plot``, the friction plot, and the diagnosis report -- the one
exception, marked as expected to fail while its figures are rewritten.
"""

from __future__ import annotations

import contextlib
import re
from pathlib import Path

import numpy as np
import pytest

from pneusim.cli import main
from pneusim.experiment import standard_experiment
from pneusim.plotting import figure_problems
from pneusim.recording import write_recording
from pneusim.simulate import simulate

from ablation_cases import DEADBAND, write_tiny_ablation

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
DATA = ROOT / "tests" / "pneusim" / "scenario" / "data"
_TEMPORARY = re.compile(r"^\.(?P<stem>.+)\.[0-9a-f]+\.tmp(?P<suffix>\.\w+)$")   # pneusim.outputs' atomic writes


def _written_name(fname) -> str:
    """The file a figure is saved as (the final name, for an atomic write's temporary file)."""
    name = Path(str(fname)).name
    m = _TEMPORARY.match(name)
    return m.group("stem") + m.group("suffix") if m else name


@contextlib.contextmanager
def checked_figures():
    """Check every figure saved inside the block; yields ``{file name: [problems]}``."""
    from matplotlib.figure import Figure

    found = {}
    original = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        name = _written_name(fname)
        found[name] = figure_problems(self, name)
        return original(self, fname, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", savefig)
        yield found


def assert_standard(found: dict, folder=None, expected=()) -> None:
    """No problem in any checked figure; every PNG of ``folder`` checked; the ``expected`` names among them."""
    problems = [p for name in sorted(found) for p in found[name]]
    assert problems == [], "figures below the standard:\n" + "\n".join(problems)
    if folder is not None:
        unchecked = sorted({p.name for p in Path(folder).glob("*.png")} - set(found))
        assert unchecked == [], f"PNG written without passing through savefig: {unchecked}"
    missing = sorted(set(expected) - set(found))
    assert missing == [], f"expected figures not made: {missing}; made: {sorted(found)}"


# ------------------------------------------------------------------ the checker itself
def test_the_checker_finds_what_a_figure_lacks():
    from pneusim.plotting import new_figure, pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 3))
    t = np.linspace(0.0, 1.0, 200)
    ax.plot(t, np.sin(6 * t), label="a")
    ax.plot(t, np.cos(6 * t), label="b")
    ax.set_ylim(-0.3, 0.3)                                # the curves fill the axes: a legend must cover them
    ax.legend(loc="center", fontsize=14)
    problems = figure_problems(fig, "bare")
    plt.close(fig)
    assert any("no title" in p for p in problems)
    assert any("x axis has tick labels but no label" in p for p in problems)
    assert any("the legend covers" in p and "'a'" in p for p in problems)
    fig, ax = new_figure(title="A long title " * 20, size=(4, 3))
    ax.plot(t, t)
    ax.set_xlabel("time")
    ax.set_ylabel("position (mm)")
    problems = figure_problems(fig, "cut")
    plt.close(fig)
    assert any("the title reaches beyond the figure's edge" in p for p in problems)
    assert any("'time' gives no unit" in p for p in problems)


# ------------------------------------------------------------------ scenario reports
_SCENARIO_RUNS = {
    "tiny-open-loop": (DATA / "tiny-open-loop.toml", [], ["recording.png", "validation.png",
                                                          "rls-rls-2-h1.png"]),
    "tiny-generalisation": (DATA / "tiny-generalisation.toml", [],
                            ["recording.png", "validation.png", "generalisation-supply-2-bar.png",
                             "generalisation.png"]),
    # the papers' published models, without the physical fit (the expensive row) on short records
    "paper1": (SCENARIOS / "paper1-online-rls.toml", ["experiment.duration_s=2.0", "identifiers.6.enabled=false"],
               ["recording.png", "published-z.png", "rls-rls-arma-order-4-h5.png"]),
    "paper2": (SCENARIOS / "paper2-multisine.toml", ["experiment.duration_s=10.0", "identifiers.5.enabled=false"],
               ["recording.png", "validation.png", "published-s.png", "variant-literal-open-loop-reading.png"]),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(_SCENARIO_RUNS))
def test_scenario_report_figures(name, tmp_path):
    path, sets, expected = _SCENARIO_RUNS[name]
    out = tmp_path / "report"
    args = ["run", str(path), "--out", str(out), "--no-progress"] + [a for s in sets for a in ("--set", s)]
    with checked_figures() as found:
        assert main(args) == 0
    assert_standard(found, out, expected)
    page = (out / "report.html").read_text()
    assert page.count("data:image/png;base64,") == len(list(out.glob("*.png")))


def _table():
    """A sweep table as ``build_table`` writes it: supply pressure on a grid, a random mass, four black-box
    models near 95 %, one failing run of one model far below, and the paper's eq. 4 under two readings."""
    rng = np.random.default_rng(0)
    rows = []
    for k, (supply, mass) in enumerate((s, m) for s in (501325.0, 601325.0, 701325.0) for m in (0.8, 1.6, 2.4)):
        for ident, level in (("ARX", 95.5), ("ARMAX", 95.9), ("State Space", 95.6),
                             ("General Transfer Function", 94.9)):
            fit = level + rng.normal(0.0, 0.6) - (60.0 if (ident == "ARMAX" and k == 4) else 0.0)
            rows.append({"run_id": f"r{k}", "rig.overrides.supply_Pa": supply, "rig.overrides.moving_mass_kg": mass,
                         "identifiers.0.orders": "[3, 3, 1]", "identifier": ident,
                         "reading": "simulation, estimated initial state", "status": "ok", "fit_percent": fit})
        for reading, level in (("time unit = ms", -426.0), ("time unit = sample", -90.0)):
            rows.append({"run_id": f"r{k}", "rig.overrides.supply_Pa": supply, "rig.overrides.moving_mass_kg": mass,
                         "identifiers.0.orders": "[3, 3, 1]", "identifier": "published eq. 4", "reading": reading,
                         "status": "ok", "fit_percent": level + rng.normal(0.0, 1.0)})
    return rows


@pytest.mark.slow
def test_sweep_summary_figures_show_the_differences(tmp_path):
    from pneusim.plotting import figure_hook
    from pneusim.scenario.sweep_plots import summary_plots

    axes = {}

    def keep(fig, path):
        main_panel = fig.axes[0]
        axes[path.name] = (main_panel.get_ylim(), fig.axes[-1].get_xlabel(), fig.axes[-1].get_xlim(),
                           fig.get_suptitle(), [t.get_text() for t in main_panel.get_legend().get_texts()])

    keys = ["rig.overrides.supply_Pa", "rig.overrides.moving_mass_kg", "identifiers.0.orders"]
    with checked_figures() as found, figure_hook(keep):
        paths = summary_plots(_table(), keys, tmp_path)
    assert_standard(found, tmp_path, [p.name for p in paths])
    ylim, xlabel, xlim, title, legend = axes["summary-rig.overrides.supply_Pa.png"]
    assert xlabel == "supply pressure (bar gauge)" and 3.5 < xlim[0] < 4.0 and 6.0 < xlim[1] < 6.5
    assert ylim[0] > 85.0 and ylim[1] <= 100.5       # the good models' differences, the failing run clipped
    assert "supply pressure" in title
    assert all("published" not in text for text in legend)            # eq. 4 has a panel of its own
    assert any(text.startswith("ARX (median 9") for text in legend)


@pytest.mark.slow
def test_sweep_and_ablation_figures_of_a_run(tmp_path):
    """A tiny ablation through the sweep: its summary figures and ablation.png."""
    from pneusim.scenario.sweep import load_sweep, run_sweep

    path = write_tiny_ablation(tmp_path, DEADBAND, duration_s=6.0)
    out = tmp_path / "out"
    with checked_figures() as found:
        info = run_sweep(load_sweep(path), out, workers=0, progress=False)
    assert info["n_failed"] == 0
    assert_standard(found, out, ["ablation.png"])


# ------------------------------------------------------------------ MRE, fit, plot, friction
@pytest.mark.slow
def test_mre_report_figures(tmp_path):
    from pneusim.mre.run import run_mre
    from pneusim.mre.scenario import validate_mre

    spec = validate_mre({
        "mre": {"name": "t", "duration_s": 0.3, "warmup_s": 0.05, "seed": 3},
        "rig": {"name": "paper1-mre"},
        "controller": {"kind": "proportional", "kp_V_per_m": 40.0},
        "reference": {"kind": "pulses", "unit": "m", "base": 0.01, "amplitude": [0.01, 0.03],
                      "width_s": [0.05, 0.1], "rest_s": [0.05, 0.1], "sign": "positive"},
        "identifiers": [{"name": "RLS ARMA order 4", "kind": "rls", "order": 4, "horizons": [1, 5]},
                        {"name": "sysid order 3", "kind": "recursive_arx", "order": 3}]}, "test.toml")
    out = tmp_path / "mre"
    with checked_figures() as found:
        run_mre(spec, out, mode="fast")
    assert_standard(found, out, ["response.png", "predictions.png", "coefficients.png", "timing.png"])


@pytest.fixture(scope="module")
def recording_file(tmp_path_factory, rig2):
    exp = standard_experiment(rig2, "pulses", 12.0, "open", seed=5)
    path = tmp_path_factory.mktemp("figures") / "run.csv"
    write_recording(simulate(rig2, exp, seed=6).recording, path)
    return path


@pytest.mark.slow
def test_fit_report_figure_and_page(recording_file, tmp_path):
    out = tmp_path / "fit"
    with checked_figures() as found:
        assert main(["fit", str(recording_file), "--report", str(out), "--quiet"]) == 0
    assert_standard(found, out, ["fit.png"])
    page = (out / "index.html").read_text()
    assert page.count("data:image/png;base64,") == 1 and "<table>" in page
    md = (out / "report.md").read_text()
    assert "| pressure in chamber A |" in md and "; pressure_a_Pa" not in md


@pytest.mark.slow
def test_plot_command_figure(recording_file, tmp_path):
    with checked_figures() as found:
        assert main(["plot", str(recording_file), "--out", str(tmp_path / "run.png")]) == 0
    assert_standard(found, tmp_path, ["run.png"])


@pytest.mark.slow
def test_friction_plot_figure(shared_dir, tmp_path):
    files = sorted((shared_dir / "data" / "real" / "cylinder_seal_friction_tudelft2021").glob("*.csv"))
    with checked_figures() as found:
        assert main(["friction", *map(str, files), "--plot", str(tmp_path / "friction.png")]) == 0
    assert_standard(found, tmp_path, ["friction.png"])


# ------------------------------------------------------------------ the diagnosis report
@pytest.mark.slow
def test_diagnosis_report_figures(shared_dir, tmp_path):
    """A quick practice2 case (a 0.37 V dead band, the first 30 s: about 30 s to diagnose) with one finding."""
    from pneusim.diagnosis import diagnose, write_report
    from pneusim.recording import read_recording

    result = diagnose(read_recording(shared_dir / "practice2" / "practice2_20.csv").slice(0.0, 30.0))
    with checked_figures() as found:
        write_report(result, tmp_path / "diagnosis")
    assert_standard(found, tmp_path / "diagnosis", ["fit.png", "residuals.png"])
