"""``pneusim run``: run a scenario and write its report."""

from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("run", help="run a scenario (scenarios/*.toml) and write its report",
                       description="Simulate a scenario, score its identifiers and write report.md, report.html "
                                   "(figures embedded), metrics.json, the recordings and PNG figures.")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario file (.toml), see scenarios/README.md")
    p.add_argument("--out", metavar="DIR", help="output directory (default: results/<scenario name>)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", default=[],
                   help="override a scenario key by its dotted path (TOML value), e.g. experiment.duration_s=5")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..scenario import load_scenario, run_scenario, validate_scenario, write_report
    from ..scenario.sweep import parse_set_items
    from ..scenario.schema import set_dotted

    spec = load_scenario(args.scenario)
    if args.set:
        for key, value in parse_set_items(args.set).items():
            set_dotted(spec, key, value, where="--set")
        spec = validate_scenario(spec, where=f"{args.scenario} with --set")
    out = Path(args.out or Path("results") / spec["scenario"]["name"])
    result = run_scenario(spec, progress=not args.no_progress)
    write_report(result, out, scenario_path=args.scenario)
    ok = sum(r["status"] == "ok" for r in result.rows)
    print(f"wrote {out}/report.md, report.html, metrics.json: {ok} of {len(result.rows)} rows scored, "
          f"{result.timings_s['total_s']:.1f} s")
    for r in result.rows:
        if r["status"] != "ok":
            print(f"  {r['identifier']}: {r['status']} ({r.get('reason', '')})")
    return 0
