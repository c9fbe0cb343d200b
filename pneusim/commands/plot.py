"""``pneusim plot``: draw a recording (position and reference, valve command, pressures)."""

from __future__ import annotations

from ..plots import plot_recording
from ..recording import read_recording
from .common import output_file


def register(sub) -> None:
    p = sub.add_parser("plot", help="plot a recording (PNG or SVG)",
                       description="Draw a pneusim-recording/1 file: position (and reference), valve command and, "
                                   "when recorded, chamber pressures over time.")
    p.add_argument("recording", metavar="RECORDING", help="pneusim-recording/1 file (.csv or .mat)")
    p.add_argument("--out", required=True, metavar="FIG", help="figure file, .png or .svg")
    p.set_defaults(func=run)


def run(args) -> int:
    output_file(args.out, "--out", (".png", ".svg"))
    plot_recording(read_recording(args.recording), args.out)
    print(f"wrote {args.out}")
    return 0
