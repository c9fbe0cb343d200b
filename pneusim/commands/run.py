"""``pneusim run``: run a scenario and write its report."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..runid import run_context
from .common import add_overwrite_argument, results_folder

#: what a scenario's report folder holds (pneusim.scenario.report.write_report); the PNG figures vary
REPORT_FILES = ("report.md", "report.html", "metrics.json", "recording.csv", "predictions.csv", "variant-*.csv",
                "*.png")

EXAMPLES = """examples:
  pneusim run scenarios/paper1-online-rls.toml --out results/paper1
  pneusim run scenarios/paper2-multisine.toml --out results/paper2
  pneusim run scenarios/paper2-multisine.toml --set experiment.duration_s=20 --set rig.overrides.moving_mass_kg=2.0

Writes into DIR: report.md, report.html (self-contained, figures embedded), metrics.json (every number of
the report), recording.csv and variant-*.csv (the simulated runs, pneusim-recording/1), predictions.csv (each
model's output beside the data it was scored on) and the PNG figures.  DIR holding the results of another
run (another scenario, other --set values, a changed rig file) is refused unless --overwrite is given; the
same run again replaces its own results.  The schema of scenario files is documented in scenarios/README.md."""


def register(sub) -> None:
    p = sub.add_parser("run", help="run a scenario (scenarios/*.toml) and write its report",
                       description="Simulate a scenario, score its identifiers and write its report.",
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", metavar="SCENARIO", help="scenario file (.toml), see scenarios/README.md")
    p.add_argument("--out", metavar="DIR", help="output directory (default: results/<scenario name>)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", default=[],
                   help="change a scenario key by its dotted path for this run (VALUE is a TOML value), "
                        "e.g. experiment.duration_s=5 or identifiers.0.order=4; repeatable")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_overwrite_argument(p)
    p.set_defaults(func=run)


def run(args) -> int:
    # the scenarios import SciPy, sysid and the fit (about a second): imported when the command runs, so
    # that pneusim --help and the other commands start without them
    from ..scenario import load_scenario, run_scenario, validate_scenario, write_report
    from ..scenario.schema import set_dotted
    from ..scenario.sweep import parse_set_items

    spec = load_scenario(args.scenario)
    if args.set:
        where = f"{args.scenario} --set"
        for key, value in parse_set_items(args.set).items():
            set_dotted(spec, key, value, where=where)
        spec = validate_scenario(spec, where=where)
    out = Path(args.out or Path("results") / spec["scenario"]["name"])
    # the folder's run is the validated scenario (the --set values applied) and the rig files it names
    folder = results_folder(args, out, "--out", run_context(spec), known=REPORT_FILES,
                            markers=("metrics.json", "report.html"), inputs={"the scenario file": args.scenario})
    result = run_scenario(spec, progress=not args.no_progress)
    write_report(result, out, scenario_path=args.scenario, overrides=list(args.set))
    folder.finish()
    ok = sum(r["status"] == "ok" for r in result.rows)
    print(f"wrote {out}/report.md, report.html, metrics.json: {ok} of {len(result.rows)} rows scored, "
          f"{result.timings_s['total_s']:.1f} s")
    for r in result.rows:
        if r["status"] != "ok":
            print(f"  {r['identifier']}: {r['status']} ({r.get('reason', '')})")
    return 0
