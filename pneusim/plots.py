"""Plots of recordings (PNG or SVG by the file suffix)."""

from __future__ import annotations

from pathlib import Path

from .errors import PneusimError
from .recording import Recording

__all__ = ["plot_recording"]


def plot_recording(recording: Recording, path, title: str | None = None):
    """Position (and reference), valve command and pressures over time, one panel each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    if path.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise PneusimError(f"--plot {path}: expected a .png, .svg or .pdf file name")
    panels = 3 if recording.has_pressures else 2
    fig, axes = plt.subplots(panels, 1, sharex=True, figsize=(9, 2.4 * panels))
    t = recording.time_s
    axes[0].plot(t, recording.position_m * 1e3, lw=0.8, label="position")
    if recording.reference_m is not None:
        axes[0].plot(t, recording.reference_m * 1e3, lw=0.8, ls="--", label="reference")
    axes[0].set_ylabel("position (mm)")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[1].plot(t, recording.valve_cmd_V, lw=0.8, color="C2")
    axes[1].set_ylabel("valve command (V)")
    if recording.has_pressures:
        axes[2].plot(t, recording.pressure_a_Pa / 1e5, lw=0.8, label="A (cap)")
        axes[2].plot(t, recording.pressure_b_Pa / 1e5, lw=0.8, label="B (rod)")
        axes[2].set_ylabel("pressure (bar abs)")
        axes[2].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(title or f"{recording.rig or 'recording'} — {recording.loop or ''} loop")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
