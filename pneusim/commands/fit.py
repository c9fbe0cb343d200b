"""``pneusim fit``: fit the rig's physical parameters to a recording."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from ..outputs import file_digest, write_json_atomic
from ..plausibility import check_plausible
from ..recording import read_recording
from ..rig import write_rig
from .common import (add_overwrite_argument, add_rig_arguments, number_type, output_file, parse_effects,
                     refuse_inputs_as_outputs, results_folder, rig_for_recording)

#: what ``--report DIR`` holds (pneusim.fit.report.write_fit_report)
REPORT_FILES = ("index.html", "report.md", "fit.json", "fit.png")


def register(sub) -> None:
    p = sub.add_parser(
        "fit", help="fit the physical model's parameters to a recording (CasADi + IPOPT)",
        description="Estimate the rig's uncertain parameters (valve conductance and critical pressure ratio, "
                    "friction, moving mass, and the parameters of any effect switched on) from a recording, "
                    "with standard errors, correlations and a validation fit on data the fit never saw.",
        epilog="examples:\n  pneusim fit run.csv --json fit.json --report fit-report\n"
               "  pneusim fit run.csv --effect valve_deadband:deadband_V=0.2 --free friction_coulomb_N "
               "--free valve_deadband.deadband_V\n"
               "      (only these two are fitted: --free replaces the default list)\n\n"
               "exit status: 0 fitted; 2 bad input (one line on stderr); 3 fitted, but the residual stays far\n"
               "above the sensor noise (residual rms / noise std above 1.5 for some measured signal: the model\n"
               "does not explain the recording; the result is still written). Above 1.1 the result says\n"
               "converged_to_noise: false and success: false and carries a warning.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recording", metavar="RECORDING", help="pneusim-recording/1 file (.csv or .mat)")
    add_rig_arguments(p)
    p.add_argument("--free", action="append", metavar="NAME",
                   help="a parameter to fit (repeatable); the parameters given replace the default list (valve "
                        "conductance and critical pressure ratio, friction, moving mass, plus the parameters of "
                        "the effects switched on): list every parameter to fit")
    p.add_argument("--validation-fraction", type=number_type("a fraction in (0, 1)", 0.0, 1.0, low_included=False,
                                                             high_included=False), default=0.3, metavar="F",
                   help="final fraction of the recording kept for validation (default 0.3)")
    p.add_argument("--json", metavar="OUT.json", help="write the result as JSON")
    p.add_argument("--report", metavar="DIR", help="write index.html (self-contained), report.md, fit.json and "
                   "fit.png into DIR")
    add_overwrite_argument(p, "fit report")
    p.add_argument("--quiet", action="store_true", help="print only the validation fit")
    p.add_argument("--rig-out", metavar="FITTED.toml", help="write the rig with the fitted values as a rig file "
                   "that --rig accepts")
    p.set_defaults(func=run)


def run(args, fit_recording=None) -> int:
    """The command; ``fit_recording`` replaces :func:`pneusim.fit.fit_recording` (tests stop before fitting)."""
    # the fit imports SciPy's optimisers (about a second): imported when the command runs, so that
    # pneusim --help and the other commands start without it
    from ..fit import fit_recording as fit
    from ..fit.report import write_fit_report
    from ..fit.result import FAR_ABOVE_NOISE

    fit_recording = fit_recording or fit
    if args.json:
        output_file(args.json, "--json", (".json",))
    if args.rig_out:
        output_file(args.rig_out, "--rig-out", (".toml",))
    recording = read_recording(args.recording)
    rig_file = args.rig if args.rig and args.rig.lower().endswith(".toml") else None
    inputs = {"the recording": args.recording, "the rig file given with --rig": rig_file,
              "the rig file the recording names (rig_file)": None if args.rig else recording.metadata.get("rig_file")}
    refuse_inputs_as_outputs({"--json": args.json, "--rig-out": args.rig_out}, inputs)
    rig = rig_for_recording(recording, args.recording, args.rig, args.param)
    check_plausible(recording, rig)   # a 1e30 V command or pressures in bar are refused before any work
    folder = None
    if args.report:
        identity = {"recording": file_digest(args.recording), "rig": rig.params, "rig_name": rig.name,
                    "effects": list(args.effect or []), "free": args.free, "validation": args.validation_fraction}
        folder = results_folder(args, args.report, "--report", identity, known=REPORT_FILES, inputs=inputs)
    mismatch = None
    if args.rig and recording.rig and recording.rig != rig.name:
        mismatch = (f"--rig {args.rig} ({rig.name}) differs from the rig the recording names ('rig: "
                    f"{recording.rig}'): the fit describes {recording.rig}'s data with {rig.name}'s known values")
        print(f"pneusim fit: warning: {mismatch}", file=sys.stderr)
    effects = parse_effects(args.effect)
    result = fit_recording(recording, rig, effects, free=args.free, validation_fraction=args.validation_fraction,
                           quiet=args.quiet)
    if mismatch:
        result.warnings.insert(0, mismatch)   # in the summary, the JSON and the report
    if args.quiet:
        print(f"validation fit {result.fit_percent:.2f} %")
    else:
        print(result.summary())
    if args.json:
        write_json_atomic(args.json, result.to_dict(), indent=1)
        print(f"wrote {args.json}")
    if args.report:
        print(f"wrote {write_fit_report(result, args.report)}")
        folder.finish()
    if args.rig_out:
        fitted = dataclasses.replace(result.rig_, name=Path(args.rig_out).stem,
                                     description=f"{rig.name} fitted to {args.recording} (pneusim fit)")
        write_rig(fitted, args.rig_out, getattr(result, "effects_", ()))
        print(f"wrote {args.rig_out} (use it with --rig {args.rig_out})")
    if result.normalised_residual > FAR_ABOVE_NOISE:
        print(f"pneusim fit: the residual is {result.normalised_residual:.2f} times the sensor noise (above "
              f"{FAR_ABOVE_NOISE}): the model does not explain this recording (exit status 3)", file=sys.stderr)
        return 3
    return 0
