"""``pneusim fit``: fit the rig's physical parameters to a recording."""

from __future__ import annotations

from ..errors import PneusimError
from ..recording import read_recording
from .common import add_rig_arguments, output_file, output_folder, parse_effects, rig_with_overrides


def register(sub) -> None:
    p = sub.add_parser(
        "fit", help="fit the physical model's parameters to a recording (CasADi + IPOPT)",
        description="Estimate the rig's uncertain parameters (valve conductance and critical pressure ratio, "
                    "friction, moving mass, and the parameters of any effect switched on) from a recording, "
                    "with standard errors, correlations and a validation fit on data the fit never saw.",
        epilog="examples:\n  pneusim fit run.csv --json fit.json --report fit-report\n"
               "  pneusim fit run.csv --effect valve_deadband:deadband_V=0.2 --free friction_coulomb_N "
               "--free valve_deadband.deadband_V",
        formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("recording", metavar="RECORDING", help="pneusim-recording/1 file (.csv or .mat)")
    add_rig_arguments(p)
    p.add_argument("--free", action="append", metavar="NAME",
                   help="a parameter to fit (repeatable; default: valve conductance and critical pressure ratio, "
                        "friction, moving mass, plus the parameters of the effects switched on)")
    p.add_argument("--validation-fraction", type=float, default=0.3, metavar="F",
                   help="final fraction of the recording kept for validation (default 0.3)")
    p.add_argument("--json", metavar="OUT.json", help="write the result as JSON")
    p.add_argument("--report", metavar="DIR", help="write report.md, fit.json and fit.png into DIR")
    p.add_argument("--quiet", action="store_true", help="print only the validation fit")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..fit import fit_recording

    if args.json:
        output_file(args.json, "--json", (".json",))
    if args.report:
        output_folder(args.report, "--report")
    recording = read_recording(args.recording)
    rig_name = args.rig or recording.rig
    if not rig_name:
        raise PneusimError(f"{args.recording} names no rig in its metadata ('# rig: ...'); give --rig")
    rig = rig_with_overrides(rig_name, args.param)
    effects = parse_effects(args.effect)
    result = fit_recording(recording, rig, effects, free=args.free, validation_fraction=args.validation_fraction,
                           verbose=not args.quiet)
    if args.quiet:
        print(f"validation fit {result.fit_percent:.2f} %")
    else:
        print(result.summary())
    if args.json:
        result.write_json(args.json)
        print(f"wrote {args.json}")
    if args.report:
        from ..fit.report import write_fit_report
        print(f"wrote {write_fit_report(result, args.report)}")
    return 0
