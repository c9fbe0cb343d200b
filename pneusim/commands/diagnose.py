"""``pneusim diagnose``: locate the mismatch, name the physics left out, model it, show the fit improve."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from ..errors import PneusimError
from ..model import EFFECTS
from ..outputs import file_digest, same_file, write_json_atomic
from ..plausibility import check_plausible
from ..recording import read_recording
from .common import (add_overwrite_argument, load_rig_file, output_file, refuse_inputs_as_outputs, results_folder,
                     rig_for_recording)

#: what a diagnosis report folder holds (pneusim.diagnosis.report.write_report)
REPORT_FILES = ("index.html", "report.md", "diagnosis.json", "*.png")
#: what the folder of several recordings' diagnoses holds beside their report folders
BATCH_FILES = ("summary.csv", "summary.md", "*.json", "*/index.html", "*/report.md", "*/diagnosis.json", "*/*.png")

EXAMPLES = """examples:
  pneusim diagnose run.csv --json diagnosis.json --report diagnosis/     # open diagnosis/index.html
  pneusim diagnose run.csv --effect valve_deadband --effect leakage       # consider only these effects
  pneusim diagnose ../shared/practice2 --report results/practice2          # a folder: one report per file
  pneusim diagnose a.csv b.csv --report out --dask local --workers 2      # on a loopback Dask cluster

One recording: prints the findings (the JSON of shared/spec/diagnosis.md with --json; the report folder
with --report: index.html, report.md, fit.png, zoom.png, residuals.png, one evidence plot per finding).
Several recordings or a folder: runs them in parallel (local processes by default, or Dask)
and writes DIR/NAME/ (report), DIR/NAME.json and DIR/summary.csv + summary.md (one row per recording;
a recording that fails is a row with its error, the others go on; NAME is the file's stem, told apart
where two recordings share one).  A recording is checked against its rig first (the rig that made it,
values it could have recorded).  A DIR holding the results of another diagnosis is refused unless
--overwrite is given.  Exit code 2 for bad input, and when any of several recordings failed."""


def register(sub) -> None:
    p = sub.add_parser("diagnose", help="find which physics the nominal model leaves out of a recording",
                       description="Fit the nominal model, locate where it misses the recording beyond noise, "
                                   "name the missing effect from the vocabulary with its evidence, model it "
                                   "(refit with the effect switched on) and show the validation fit improve; "
                                   "'nothing is missing' when no effect passes the test.",
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recordings", metavar="RECORDING", nargs="+",
                   help="pneusim-recording/1 file(s) (.csv or .mat) or folder(s) of them")
    p.add_argument("--rig", help="rig name (paper1-mre, paper2-enfield) or rig file (.toml); default: the "
                                 "recording's metadata")
    p.add_argument("--effect", action="append", metavar="NAME",
                   help="consider only these vocabulary effects (repeatable; default all)")
    p.add_argument("--validation-fraction", type=float, default=0.3, metavar="F",
                   help="final fraction kept for validation, never fitted (default 0.3)")
    p.add_argument("--max-refits", type=int, default=3, metavar="K",
                   help="leading candidates confirmed by a whole refit, one per look-alike family (default 3)")
    p.add_argument("--max-lookalikes", type=int, default=2, metavar="K",
                   help="look-alikes of the winning candidate refitted after them (default 2)")
    p.add_argument("--several-effects", action=argparse.BooleanOptionalAction, default=None,
                   help="search for several effects at once from the first finding on (up to 3, each tested with "
                        "the others present, 'other' where the findings leave physics unexplained, within a time "
                        "budget); --no-several-effects never goes beyond the one-effect-first search (default: "
                        "go on from its findings where they leave the recording unexplained)")
    p.add_argument("--max-findings", type=int, default=None, metavar="K",
                   help="at most this many vocabulary effects modelled together (default 2; 3 with "
                        "--several-effects)")
    p.add_argument("--time-budget", type=float, default=None, metavar="SECONDS",
                   help="seconds a recording's diagnosis may take on the reference machine (counted in model "
                        "work, so the answer is the same on every machine): no fit runs past it, and the result, "
                        "with what was found before, says so (default: ten times the nominal fit's, at least "
                        "240; 240 with --several-effects; none with --no-several-effects)")
    p.add_argument("--json", metavar="OUT.json", help="write the JSON result (one recording)")
    p.add_argument("--report", metavar="DIR", help="write the report folder (open DIR/index.html); for "
                                                   "several recordings, the folder of all reports and the summary")
    p.add_argument("--dask", metavar="ADDRESS", default=None,
                   help="several recordings: a Dask scheduler (tcp://HOST:PORT) or 'local'")
    p.add_argument("--workers", metavar="N", type=int, default=None,
                   help="several recordings: local processes or Dask workers (default: CPU count; 0: in-process)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    add_overwrite_argument(p, "diagnosis")
    p.set_defaults(func=run)


def run(args) -> int:
    # the diagnosis imports SciPy and the fit (about a second): imported when the command runs, so that
    # pneusim --help and the other commands start without it
    from ..diagnosis import diagnose
    from ..diagnosis.batch import diagnose_many, expand_recordings, output_names
    from ..diagnosis.report import write_report

    for name in args.effect or []:
        if name not in EFFECTS:
            raise PneusimError(f"--effect {name}: unknown effect; expected one of: {', '.join(EFFECTS)}")
    if args.workers is not None and args.workers < 0:
        raise PneusimError(f"--workers must be >= 0, got {args.workers}")
    for option, value in (("--max-refits", args.max_refits), ("--max-lookalikes", args.max_lookalikes),
                          ("--max-findings", args.max_findings)):
        if value is not None and value < 0:
            raise PneusimError(f"{option} must be >= 0, got {value}")
    if args.time_budget is not None and not (args.time_budget > 0 and math.isfinite(args.time_budget)):
        raise PneusimError(f"--time-budget must be a positive number of seconds, got {args.time_budget}")
    if args.rig:
        load_rig_file(args.rig)  # an unknown rig is reported before any work
    files = expand_recordings(args.recordings)
    options = {"effects": args.effect, "validation_fraction": args.validation_fraction,
               "max_refits": args.max_refits, "max_lookalikes": args.max_lookalikes,
               "max_findings": args.max_findings, "several_effects": args.several_effects,
               "time_budget_s": args.time_budget}
    identity = {"recordings": [file_digest(f) for f in files], "rig": args.rig, "options": options}
    inputs = {f"the recording {f}": f for f in files}
    many = len(files) > 1 or any(Path(r).is_dir() for r in args.recordings)
    if many:
        return _diagnose_many(args, files, options, identity, inputs, diagnose_many, output_names)
    if args.json:
        output_file(args.json, "--json", (".json",))
    recording = read_recording(files[0])
    rig = rig_for_recording(recording, str(files[0]), args.rig)
    check_plausible(recording, rig)    # the rig that made it, values it could have recorded: before any work
    if args.rig and recording.rig and recording.rig != rig.name:
        print(f"pneusim diagnose: warning: --rig {args.rig} ({rig.name}) differs from the rig the recording names "
              f"('rig: {recording.rig}'): the diagnosis reads {recording.rig}'s data with {rig.name}'s known values",
              file=sys.stderr)
    folder = None
    if args.report:
        folder = results_folder(args, args.report, "--report", identity, known=REPORT_FILES,
                                markers=("index.html", "diagnosis.json"), inputs=inputs)
    result = diagnose(recording, rig, progress=not args.quiet, **options)
    print(result.summary())
    if args.json:
        write_json_atomic(args.json, result.to_dict(), indent=1, allow_nan=False)
        print(f"wrote {args.json}")
    if args.report:
        print(f"wrote {write_report(result, args.report)}")
        folder.finish()
    return 0


def _diagnose_many(args, files, options, identity, inputs, diagnose_many, output_names) -> int:
    """Several recordings: the report folder checked, the diagnoses run, one line each and the summary."""
    if args.json:
        raise PneusimError("--json writes one recording's result; with several recordings give --report DIR "
                           "(each result is DIR/NAME.json, the table DIR/summary.csv)")
    if not args.report:
        raise PneusimError("several recordings need --report DIR for their results and the summary table")
    for item in args.recordings:
        if Path(item).is_dir() and Path(args.report).is_dir() and same_file(item, args.report):
            raise PneusimError(f"--report {args.report}: that is a folder of the recordings diagnosed ({item}); "
                               "its results would be read as recordings next time: give another folder")
    out = Path(args.report)
    refuse_inputs_as_outputs({"--report": [out / "summary.csv", out / "summary.md"]
                              + [out / f"{n}.json" for n in output_names(files)]}, inputs)
    folder = results_folder(args, out, "--report", identity, known=BATCH_FILES, markers=("summary.csv",),
                            inputs=inputs)
    rows = diagnose_many(files, out, args.rig, workers=args.workers, dask=args.dask, progress=not args.quiet,
                         **options)
    folder.finish()
    failed = [r for r in rows if r["status"] != "ok"]
    for r in rows:
        state = r["findings"] if r["status"] == "ok" else f"FAILED: {r['error']}"
        print(f"{r['recording']}: {state}")
    print(f"wrote {out}/summary.csv and summary.md: {len(rows)} recordings, {len(failed)} failed")
    if failed:
        raise PneusimError(f"{len(failed)} of {len(rows)} recordings failed (their errors are in "
                           f"{out / 'summary.csv'}); the others' results are written")
    return 0
