"""Plots of recordings (PNG, SVG or PDF by the file suffix), in the figure standard of :mod:`pneusim.plotting`."""

from __future__ import annotations

from pathlib import Path

from .errors import PneusimError
from .plotting import COLOURS, bar_gauge, mm, new_figure, save_figure
from .recording import Recording

__all__ = ["plot_recording", "recording_figure"]


def recording_figure(recording: Recording, title: str | None = None):
    """The figure of a recording: position in mm (and the reference), the valve command in V and the chamber
    pressures in bar gauge over time, one panel each; returns ``(figure, axes)``."""
    panels = 3 if recording.has_pressures else 2
    what = "position, valve command and chamber pressures" if recording.has_pressures else \
        "position and valve command"
    title = title or f"{recording.rig or 'recording'}, {recording.loop or ''} loop: {what} over time"
    fig, axes = new_figure(panels, 1, title=title, size=(9, 2.3 * panels + 0.6), sharex=True)
    t = recording.time_s
    axes[0].plot(t, mm(recording.position_m), lw=0.9, color=COLOURS["measured"], label="position (measured)")
    if recording.reference_m is not None:
        axes[0].plot(t, mm(recording.reference_m), lw=0.9, ls="--", color=COLOURS["reference"], label="reference")
        axes[0].legend(fontsize=8)
    axes[0].set_ylabel("position (mm)")
    axes[1].plot(t, recording.valve_cmd_V, lw=0.8, color=COLOURS["command"])
    axes[1].set_ylabel("valve command (V)")
    if recording.has_pressures:
        axes[2].plot(t, bar_gauge(recording.pressure_a_Pa), lw=0.8, color=COLOURS["chamber_a"], label="chamber A (cap)")
        axes[2].plot(t, bar_gauge(recording.pressure_b_Pa), lw=0.8, color=COLOURS["chamber_b"], label="chamber B (rod)")
        axes[2].set_ylabel("pressure (bar gauge)")
        axes[2].legend(fontsize=8)
    axes[-1].set_xlabel("time (s)")
    return fig, axes


def plot_recording(recording: Recording, path, title: str | None = None):
    """Write :func:`recording_figure` to ``path`` (.png, .svg or .pdf); returns the path."""
    path = Path(path)
    if path.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise PneusimError(f"--plot {path}: expected a .png, .svg or .pdf file name")
    fig, _ = recording_figure(recording, title)
    return save_figure(fig, path, dpi=120)
