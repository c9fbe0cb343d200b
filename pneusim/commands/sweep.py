"""``pneusim sweep``: vary scenario keys over a grid or random draws; locally or on Dask."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import PneusimError
from .common import results_folder

#: what a sweep writes beside its runs/ (a cache kept across sweeps, keyed on everything that determines a run)
SWEEP_FILES = ("sweep.csv", "sweep.parquet", "summary-*.png", "ablation.md", "ablation.csv", "ablation.json",
               "ablation.png")

EXAMPLES = """examples:
  pneusim sweep scenarios/sweep-paper2.toml --out results/sweep-paper2              # local processes
  pneusim sweep scenarios/sweep-paper2.toml --out results/sweep-paper2 --workers 0  # in this process
  pneusim sweep scenarios/sweep-paper2.toml --dask local --workers 4                # a loopback Dask cluster
  pneusim sweep scenarios/sweep-paper2.toml --dask tcp://10.0.0.5:8786              # a running scheduler
  nice -n 10 pneusim sweep scenarios/ablation-paper2.toml --out results/ablation-paper2   # an effect ablation

Writes into DIR: sweep.csv and sweep.parquet (one row per run and identifier reading: run_id, seed, one
column per varied key, identifier, reading, status, error, metrics, times), summary-KEY.png (fit against
each varied key) and runs/RUN_ID.json (each run's result).  Runs already stored in DIR/runs are skipped,
so a sweep restarted after a crash only runs what is missing; RUN_ID hashes everything that determines
the run (scenario, [base], varied keys, seed, rig files), so a changed sweep or scenario runs again.  DIR
holding another sweep's table: its table and figures are removed (with a note) and its runs kept.  A sweep
file with an [ablation] table also writes ablation.md, ablation.csv, ablation.json and ablation.png; a run
that raises is recorded with its error and the sweep goes on.  The schema of sweep files is documented in
scenarios/README.md."""


def register(sub) -> None:
    p = sub.add_parser("sweep", help="run a scenario over a grid or random draws of its keys",
                       description="Run a sweep file: the scenario it names, once per point of its grid or "
                                   "random draws and per seed, and one tidy table of the results.",
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep", metavar="SWEEP", help="sweep file (.toml), see scenarios/README.md")
    p.add_argument("--out", metavar="DIR", help="output directory (default: results/sweep-<name>)")
    p.add_argument("--workers", metavar="N", type=int, default=None,
                   help="local processes, or Dask workers with --dask local (default: CPU count; 0: in-process)")
    p.add_argument("--dask", metavar="ADDRESS", default=None,
                   help="send the runs to a Dask distributed scheduler (tcp://HOST:PORT), or 'local' to start "
                        "a loopback LocalCluster of --workers processes")
    p.add_argument("--retry-failed", action="store_true", help="run again the runs stored as failed")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    # the scenarios import SciPy, sysid and the fit (about a second): imported when the command runs, so
    # that pneusim --help and the other commands start without them
    from ..scenario.sweep import expand_runs, load_sweep, run_sweep, sweep_run_id

    if args.workers is not None and args.workers < 0:
        raise PneusimError(f"--workers must be >= 0, got {args.workers}")
    if args.dask == "local" and args.workers == 0:
        raise PneusimError("--dask local needs --workers >= 1 (the number of Dask worker processes)")
    sweep = load_sweep(args.sweep)
    out = Path(args.out or Path("results") / f"sweep-{sweep['name']}")
    runs = [sweep_run_id(sweep, params, seed) for params, seed in expand_runs(sweep)]
    folder = results_folder(args, out, "--out", {"runs": runs, "ablation": "ablation" in sweep}, policy="replace",
                            known=SWEEP_FILES, keep=("runs",), inputs={"the sweep file": args.sweep})
    info = run_sweep(sweep, out, workers=args.workers, dask=args.dask, progress=not args.no_progress,
                     retry_failed=args.retry_failed)
    folder.finish()
    for note in info["notes"]:
        print(f"pneusim sweep: note: {note}")
    rate = f"{info['runs_per_s']:.2f} runs/s" if info["runs_per_s"] == info["runs_per_s"] else "nothing to run"
    repeated = f", {sweep['n_repeated']} repeated draws run once" if sweep.get("n_repeated") else ""
    print(f"wrote {out}/sweep.csv and sweep.parquet: {info['n_runs']} runs ({info['n_done_before']} done before, "
          f"{info['n_failed']} failed{repeated}), {len(info['table'])} rows, {rate}")
    return 0
