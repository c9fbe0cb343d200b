"""``pneusim sweep``: vary scenario keys over a grid or random draws; locally or on Dask."""

from __future__ import annotations

from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("sweep", help="run a scenario over a grid or random draws of its keys",
                       description="Run a sweep file (see scenarios/README.md): one tidy table (sweep.csv, "
                                   "sweep.parquet) with one row per run and identifier, plus summary plots. "
                                   "Runs already stored in OUT/runs are skipped.")
    p.add_argument("sweep", metavar="SWEEP", help="sweep file (.toml)")
    p.add_argument("--out", metavar="DIR", help="output directory (default: results/sweep-<name>)")
    p.add_argument("--workers", type=int, default=None,
                   help="local processes, or Dask workers with --dask local (default: CPU count; 0: in-process)")
    p.add_argument("--dask", metavar="ADDRESS", default=None,
                   help="send runs to a Dask scheduler (tcp://HOST:PORT) or 'local' for a loopback LocalCluster")
    p.add_argument("--retry-failed", action="store_true", help="re-run the runs stored as failed")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..errors import PneusimError
    from ..scenario.sweep import load_sweep, run_sweep

    if args.workers is not None and args.workers < 0:
        raise PneusimError(f"--workers must be >= 0, got {args.workers}")
    sweep = load_sweep(args.sweep)
    out = Path(args.out or Path("results") / f"sweep-{sweep['name']}")
    info = run_sweep(sweep, out, workers=args.workers, dask=args.dask, progress=not args.no_progress,
                     retry_failed=args.retry_failed)
    print(f"wrote {out}/sweep.csv and sweep.parquet: {info['n_runs']} runs ({info['n_done_before']} done before, "
          f"{info['n_failed']} failed), {len(info['table'])} rows, {info['runs_per_s']:.2f} runs/s")
    return 0
