"""``pneusim serve-rig``: serve a simulated rig over UDP, as a separate real-time target for ``pneusim mre``."""

from __future__ import annotations

import sys

from ..mre.rig_server import RigServer
from ..mre.rt import DEFAULT_PRIORITY, RealtimeScope, RealtimeSettings
from ..plant import SimulatedPlant
from ..shutdown import Terminated, sigterm_raises
from .common import (CPU, NOISE_SCALE, PRIORITY, SEED, add_rig_arguments, number_type, parse_effects,
                     rig_with_overrides)

PORT = number_type("a UDP port in 1..65535", 1, 65535, integer=True)
#: the watchdog's silence and the report interval
SECONDS = number_type("a time in s > 0", 0.0, low_included=False)
SESSIONS = number_type("a whole number >= 1", 1, integer=True)


def register(sub) -> None:
    p = sub.add_parser(
        "serve-rig", help="serve a simulated rig over UDP (for pneusim mre --plant udp:HOST:PORT)",
        description="Run the simulated rig in this process and answer one UDP datagram per sample: a command "
                    "(sequence number, timestamp) in, the next measurement out. One loop at a time: another "
                    "loop's session is refused while one is live. Lost, late, duplicated, malformed, "
                    "out-of-range and foreign datagrams are counted, refused and reported (every "
                    "--report-interval seconds and at the end); if the loop goes silent for longer than "
                    "--watchdog the valve is driven to its null and held until the next session. Ctrl-C or "
                    "SIGTERM stops the server and prints its statistics.")
    add_rig_arguments(p, rig_required=True)
    p.add_argument("--port", type=PORT, required=True, help="UDP port to listen on")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--watchdog", type=SECONDS, default=0.1, metavar="S",
                   help="silence in s after which the valve goes to its null (default 0.1)")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the sensor noise (default 0)")
    p.add_argument("--noise-scale", type=NOISE_SCALE, default=1.0, metavar="F", help="sensor noise scale (default 1)")
    p.add_argument("--report-interval", type=SECONDS, default=10.0, metavar="S",
                   help="print the counts every S seconds when they changed (default 10)")
    p.add_argument("--sessions", type=SESSIONS, default=None, metavar="N",
                   help="exit after N sessions have ended (default: serve until Ctrl-C)")
    p.add_argument("--rt-priority", type=PRIORITY, default=DEFAULT_PRIORITY, metavar="P",
                   help=f"serve at SCHED_FIFO priority P (1..99, default {DEFAULT_PRIORITY}); 0 = normal "
                        "scheduling. Where the system refuses, one line says so and the server runs "
                        "with normal scheduling")
    p.add_argument("--cpu", type=CPU, default=None, metavar="N",
                   help="pin the server to CPU N (Linux); one line says so where the system refuses")
    p.add_argument("--lock-memory", action="store_true", help="lock the server's memory (mlockall)")
    p.set_defaults(func=run)


def run(args) -> int:
    rig = rig_with_overrides(args.rig, args.param)
    plant = SimulatedPlant(rig, parse_effects(args.effect), seed=args.seed, noise_scale=args.noise_scale)
    server = RigServer(plant, args.host, args.port, watchdog_s=args.watchdog, null_V=float(rig.params["valve_null_V"]))
    host, port = server.address
    scope = RealtimeScope(RealtimeSettings(priority=args.rt_priority, cpu=args.cpu, lock_memory=args.lock_memory),
                          label="serve-rig")
    def report(line: str) -> None:
        print(f"serve-rig: {line}", flush=True)

    try:
        with sigterm_raises(), scope:
            print(f"serve-rig: {rig.name} on udp {host}:{port}, sample time {rig.sample_time_s:g} s, watchdog "
                  f"{args.watchdog:g} s, {scope.describe()}; Ctrl-C stops", flush=True)
            for notice in scope.notices:
                print(notice, file=sys.stderr, flush=True)
            server.serve(max_sessions=args.sessions, report=report, report_interval_s=args.report_interval)
    except KeyboardInterrupt as exc:
        server.stop_session("server stopped")
        print(f"serve-rig: {'terminated (SIGTERM)' if isinstance(exc, Terminated) else 'stopped'}", file=sys.stderr)
    finally:
        server.close()
    server.report_new_events(report)       # those of the last moments (the others were printed as they came)
    report(server.stats.line(server.valve_V))
    return 0
