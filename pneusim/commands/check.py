"""``pneusim check``: validate a recording and print a summary."""

from __future__ import annotations

from ..recording import read_recording, summarize


def register(sub) -> None:
    p = sub.add_parser("check", help="validate a recording and print a summary",
                       description="Read a pneusim-recording/1 file (CSV or .mat), refuse it with a clear "
                                   "message if it breaks the format, else print a summary.")
    p.add_argument("recording", metavar="RECORDING")
    p.set_defaults(func=run)


def run(args) -> int:
    rec = read_recording(args.recording)
    print(f"{args.recording}: valid pneusim-recording/1")
    print(summarize(rec))
    return 0
