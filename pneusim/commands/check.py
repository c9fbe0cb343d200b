"""``pneusim check``: validate recordings against the format and their rig, and print a summary."""

from __future__ import annotations

import sys

from ..errors import PneusimError
from ..plausibility import check_plausible, end_stop_text
from ..recording import read_recording, summarize
from .common import recording_provenance, rig_for_recording


def register(sub) -> None:
    p = sub.add_parser("check", help="validate recordings (format and plausibility for their rig) and summarise",
                       description="Read pneusim-recording/1 files (CSV or .mat), refuse each with a clear "
                                   "message if it breaks the format or cannot come from its rig (commands outside "
                                   "the valve's range, pressures outside atmosphere .. supply, positions outside "
                                   "the stroke, a sample time of another rig, an unknown rig or a rig file gone or "
                                   "changed, metadata that simulate --like would refuse), else print a summary "
                                   "with the time spent at an end stop.  Exit 0 when every file is valid, 2 "
                                   "otherwise.")
    p.add_argument("recording", metavar="RECORDING", nargs="+", help="one or more recordings (.csv or .mat)")
    p.add_argument("--rig", help="the rig to check against (a shipped name or a rig file .toml); default: the "
                                 "rig each recording names in its metadata")
    p.add_argument("--quiet", action="store_true", help="one line per file, no summary")
    p.set_defaults(func=run)


def check_one(path: str, rig_option: str | None = None):
    """Read ``path`` and check it against its rig; return ``(recording, rig)`` or raise PneusimError.

    Valid means: the format; the metadata that says what made the recording (effects, rig overrides,
    seed, noise scale), which ``pneusim simulate --like`` reads back; the rig that made it (its rig file
    still there and unchanged, with its overrides); and values that rig could have recorded."""
    rec = read_recording(path)
    recording_provenance(rec, path)
    rig = rig_for_recording(rec, path, rig_option, use_metadata_overrides=True)
    check_plausible(rec, rig)
    return rec, rig


def run(args) -> int:
    failed = 0
    many = len(args.recording) > 1
    for i, path in enumerate(args.recording):
        try:
            rec, rig = check_one(path, args.rig)
        except PneusimError as exc:
            if not many:
                raise
            failed += 1
            print(f"pneusim check: error: {exc}", file=sys.stderr)
            continue
        print(f"{path}: valid pneusim-recording/1, plausible for rig {rig.name}")
        if not args.quiet:
            if rec.rig and rec.rig != rig.name:
                print(f"note: the recording names rig {rec.rig!r}; checked against --rig {args.rig}")
            print(summarize(rec))
            print(end_stop_text(rec, rig.stroke_m))
            if many and i < len(args.recording) - 1:
                print()
    if many:
        print(f"{len(args.recording) - failed} of {len(args.recording)} files valid")
    return 2 if failed else 0
