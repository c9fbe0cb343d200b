"""Plot of a friction study: measured friction against velocity per pressure, with both fitted laws."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import PneusimError
from ..plotting import COLOURS, new_figure, pyplot, save_figure
from .study import FrictionStudy

__all__ = ["plot_friction_study"]


def plot_friction_study(study: FrictionStudy, path) -> Path:
    """One row per seal: friction vs velocity (points coloured by pressure; the nominal law dashed, the
    pressure-dependent law solid in the pressure's colour, both fitted on all pressures), and the held-out
    rms error per left-out pressure of both laws.  PNG or SVG by the suffix."""
    path = Path(path)
    if path.suffix.lower() not in (".png", ".svg"):
        raise PneusimError(f"--plot {path}: expected a .png or .svg file name")
    study._check_fitted()
    plt = pyplot()
    rows = len(study.seals_)
    verdict = ("missing: pressure_dependent_friction" if study.findings_ else "nothing is missing")
    fig, axes = new_figure(rows, 2, size=(12, 3.8 * rows + 0.6), squeeze=False, gridspec_kw={"width_ratios": [2.2, 1]},
                           title=f"Seal friction against velocity, per pressure: held-out rms error nominal law "
                                 f"{study.rms_nominal_N_:.2f} N, pressure-dependent law {study.rms_pressure_N_:.2f} N "
                                 f"-- {verdict}")
    rng = np.random.default_rng(0)
    for (ax, bars), seal in zip(axes, study.seals_):
        speed = max(np.percentile(np.abs(t.velocity_m_per_s), 99) for t in seal.tests)
        grid = np.linspace(-1.2 * speed, 1.2 * speed, 400)
        colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(seal.tests)))
        for test, colour in zip(seal.tests, colours):
            keep = rng.permutation(test.velocity_m_per_s.size)[:3000]
            ax.plot(test.velocity_m_per_s[keep] * 1e3, test.friction_N[keep], ".", ms=1.5, color=colour, alpha=0.35)
            p = np.full_like(grid, test.mean_pressure_gauge_Pa)
            ax.plot(grid * 1e3, seal.pressure.force_N(grid, p), color=colour, lw=1.8,
                    label=f"{test.mean_pressure_gauge_Pa / 1e5:.1f} bar")
        ax.plot(grid * 1e3, seal.nominal.force_N(grid, np.zeros_like(grid)), ls="--", color=COLOURS["nominal"],
                lw=1.8, label="nominal law (every pressure)")
        ax.set_xlabel("piston velocity (mm/s)")
        ax.set_ylabel("friction F - p A (N)")
        ax.set_title(f"{seal.seal}: solid = pressure-dependent law (k = {seal.pressure.theta[-1]:.2f}), "
                     "dashed = nominal", fontsize=9)
        ax.legend(fontsize=7, loc="upper left")
        ax.grid(alpha=0.3)
        x = np.arange(len(seal.folds))
        bars.bar(x - 0.2, [f["rms_nominal_N"] for f in seal.folds], 0.4, color=COLOURS["nominal"], label="nominal law")
        bars.bar(x + 0.2, [f["rms_pressure_law_N"] for f in seal.folds], 0.4, color=COLOURS["physical"],
                 label="pressure law")
        bars.set_xticks(x, [f"{f['pressure_bar']:.0f}" for f in seal.folds])
        bars.set_xlabel("pressure left out (bar gauge)")
        bars.set_ylabel("held-out rms error (N)")
        bars.set_title("fitted on the other pressures", fontsize=9)
        bars.legend(fontsize=7)
    return save_figure(fig, path)
