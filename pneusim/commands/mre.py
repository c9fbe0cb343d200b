"""``pneusim mre``: run the mixed-reality environment of an MRE file (controller, online identifiers, plant)."""

from __future__ import annotations

import os
import sys

from ..errors import PneusimError
from ..loop.sample_loop import STOP_INTERRUPTED, STOP_TERMINATED
from ..mre.plants import parse_plant
from ..mre.rt import DEFAULT_PRIORITY, RealtimeSettings
from ..mre.run import run_mre
from ..mre.scenario import load_mre
from ..shutdown import EXIT_TERMINATED, sigterm_raises
from .common import CPU, DURATION, PRIORITY, add_overwrite_argument, results_folder

#: what an MRE run writes into its folder (pneusim.mre.run.run_mre and its report)
RUN_FILES = ("recording.csv", "summary.json", "coefficients.npz", "index.html", "report.md", "*.png")


def register(sub) -> None:
    p = sub.add_parser(
        "mre", help="run controller, online identifiers and a plant in one real-time loop",
        description="Run an MRE file (example: scenarios/mre-paper1.toml): the controller and the online identifiers in one "
                    "loop at the rig's sample time, against a simulated, replayed, networked (UDP) or real (NI DAQ) "
                    "plant. The recording is written row by row to OUT/recording.csv; Ctrl-C, SIGTERM, a fault or "
                    "too many overruns stop the loop with the valve at its null and everything so far on disk. A "
                    "report (identified transfer functions, h-step predictions, coefficient traces, timing) "
                    "follows: OUT/index.html (self-contained) and report.md. An OUT holding an earlier run is refused (a measured run is never replaced) unless "
                    "--overwrite is given.")
    p.add_argument("file", metavar="FILE", help="MRE file (.toml), e.g. scenarios/mre-paper1.toml")
    p.add_argument("--plant", metavar="PLANT", default=None,
                   help="sim (the simulator), replay:FILE (a recording played back: open loop), udp:HOST:PORT "
                        "(a rig server, see pneusim serve-rig) or nidaqmx (the real rig through the rig file's "
                        "[daq] section); default: the file's mre.plant")
    p.add_argument("--duration", type=DURATION, default=None, metavar="S", help="duration in s (default: the file's)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--realtime", dest="mode", action="store_const", const="realtime",
                      help="pace the loop by the clock at the rig's sample time")
    mode.add_argument("--fast", dest="mode", action="store_const", const="fast",
                      help="run as fast as possible (rehearsal; same components and results)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    add_overwrite_argument(p, "recording, summary and report")
    p.add_argument("--no-status", action="store_true", help="no live status line")
    p.add_argument("--no-report", action="store_true", help="skip the report (recording and summary only)")
    p.add_argument("--cpu", type=CPU, default=None, metavar="N",
                   help="pin the process to CPU N during the run (Linux; os.sched_setaffinity)")
    p.add_argument("--rt-priority", type=PRIORITY, default=DEFAULT_PRIORITY, metavar="P",
                   help=f"--realtime only: run the loop at SCHED_FIFO priority P (1..99, default {DEFAULT_PRIORITY})"
                        "; 0 = normal scheduling. Where the system refuses, one line says so "
                        "and the loop runs with normal scheduling")
    p.add_argument("--lock-memory", action="store_true",
                   help="--realtime only: lock the process's memory (mlockall) while the loop runs")
    p.set_defaults(func=run, mode=None)


def run(args, run_mre=run_mre) -> int:
    """The command; ``run_mre`` replaces :func:`pneusim.mre.run.run_mre` (tests inject a fault)."""
    spec = load_mre(args.file)
    choice = parse_plant(args.plant if args.plant is not None else spec["mre"]["plant"])
    inputs = {"the MRE file": args.file, f"the recording played back (--plant {choice.text})": choice.path or None}
    folder = results_folder(args, args.out, "--out", policy="measured", known=RUN_FILES,
                            markers=("summary.json", "recording.csv", "coefficients.npz"), inputs=inputs)
    out = folder.path
    if args.cpu is not None:
        try:
            os.sched_setaffinity(0, {args.cpu})
        except (AttributeError, OSError) as exc:
            raise PneusimError(f"--cpu {args.cpu}: cannot pin the process to that CPU "
                               f"({getattr(exc, 'strerror', None) or exc})") from None
    rt = RealtimeSettings(priority=args.rt_priority, lock_memory=args.lock_memory, timer_slack=True)
    with sigterm_raises():      # SIGTERM stops the loop as Ctrl-C does: valve to null, recording and summary kept
        mr = run_mre(spec, out, plant=args.plant, mode=args.mode, duration_s=args.duration,
                     status=not args.no_status and sys.stderr.isatty(), report=not args.no_report, rt=rt)
    folder.finish()
    s = mr.summary
    for notice in s["realtime_os"]["notices"]:
        print(notice, file=sys.stderr)
    tm = s["timing"]
    print(f"{s['name']}: {s['samples']}/{s['samples_planned']} samples, plant {s['plant']}, {s['mode']}, "
          f"stopped: {s['stop_reason']}")
    if tm["lateness_s"]:
        late = tm["lateness_s"]
        print(f"lateness p50 {late['p50'] * 1e3:.3f} ms, p99 {late['p99'] * 1e3:.3f} ms, max {late['max'] * 1e3:.3f} "
              f"ms; overruns {tm['overruns']}; late > half a sample {tm['late_half_sample']} "
              f"({tm['late_half_sample_percent']:.3g} %)")
    if s["mode"] == "realtime":
        print(f"real-time settings: {s['realtime_os']['applied']}")
    if tm["compute_s"]:
        print(f"computation per sample: p50 {tm['compute_s']['p50'] * 1e3:.3f} ms, "
              f"p99 {tm['compute_s']['p99'] * 1e3:.3f} ms")
    if s["plant"].startswith("replay:"):
        print("replay plant: OPEN LOOP - the measurements were played back from the recording; the loop's "
              "commands were logged but did not act on them")
    for key, value in s["plant_counts"].items():
        if key != "rtt_s":
            print(f"plant {key}: {value}")
    for name, mdl in s["identified"].items():
        print(f"{name}: {mdl['transfer_function']}")
        if not mdl.get("finite", True):
            print(f"pneusim mre: warning: {name}: the estimate is not finite (the recursion diverged); this "
                  "transfer function says nothing about the plant", file=sys.stderr)
    print(f"written: {out / 'recording.csv'}, summary.json, coefficients.npz"
          + ("" if args.no_report else ", index.html (the report; open this one), report.md"))
    if s["stop_reason"] in (STOP_INTERRUPTED, STOP_TERMINATED):
        print(f"{s['stop_reason']}: the valve was sent to its null; the recording holds every sample taken",
              file=sys.stderr)
        return 130 if s["stop_reason"] == STOP_INTERRUPTED else EXIT_TERMINATED
    if s["stop_reason"] != "completed":
        short = " (fewer than 50: too short for pneusim check)" if s["samples"] < 50 else ""
        raise PneusimError(f"the run stopped early ({s['stop_reason']}: {s['error']}); the valve was sent to its "
                           f"null and the {s['samples']} samples taken are in {out / 'recording.csv'}{short}")
    if s.get("recording_check"):
        raise PneusimError(f"the run completed, but pneusim check refuses its recording: {s['recording_check']}")
    return 0
