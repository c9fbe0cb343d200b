"""Real-time loop of the mixed-reality environment: paper 1's loop live at 1 ms.

The loop of ``scenarios/mre-paper1.toml`` (proportional control, the paper's RLS ARMA orders 3, 4 and
5, the order-4 one with 1/5/10-step predictions) runs for ``PNEUSIM_MRE_BENCH_S`` seconds (default 60,
i.e. 60 000 samples) against

* ``sim``: the simulator in this process, paced by the clock;
* ``udp``: the rig server ``pneusim serve-rig`` in another process, one UDP datagram per sample;

each with the real-time pacing (coarse ``time.sleep`` then a busy wait of the last 0.2 ms, absolute
deadlines) and, beside it in the same session, with plain ``time.sleep`` pacing (absolute deadlines,
no busy wait); and each of these with the real-time scheduling of :mod:`pneusim.mre.rt` (``fifo``:
SCHED_FIFO priority 40 for the loop and the rig server, the default of ``--realtime``) and without it
(``normal``: ``--rt-priority 0``).  Reported per run: lateness p50/p99/max, overruns, the share of
samples late by more than half a sample (target <= 0.1 %), the loop's computation per sample, the
CPU time the hypervisor stole from the VM meanwhile (``/proc/stat``), and for UDP the lost and late
datagrams and the time from a command to reading its measurement.  Nothing is asserted about time:
the numbers depend on the machine and its load (the 1-minute load average is printed before and
after each case).  ``PNEUSIM_MRE_BENCH_CASES`` picks cases, e.g. ``sim-realtime-fifo,udp-realtime-fifo``.
The table is written to ``docs/results/mre.md`` with the commit, machine, date and command.  Run::

    nice -n -5 .venv/bin/python -m pytest benchmarks/test_bench_mre.py --benchmark-only -s
"""

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from pneusim.loop import SleepPacing
from pneusim.mre.rt import DEFAULT_PRIORITY, RealtimeSettings
from pneusim.mre.run import run_mre
from pneusim.mre.scenario import load_mre
from results_file import write_results

MRE = Path(__file__).resolve().parents[1] / "scenarios" / "mre-paper1.toml"
DURATION_S = float(os.environ.get("PNEUSIM_MRE_BENCH_S", "60"))
CASES = [(plant, pacing, sched) for plant in ("sim", "udp") for sched in ("fifo", "normal")
         for pacing in ("realtime", "sleep")]
if os.environ.get("PNEUSIM_MRE_BENCH_CASES"):
    CASES = [c for c in CASES if "-".join(c) in os.environ["PNEUSIM_MRE_BENCH_CASES"].split(",")]
RESULTS: dict = {}


def _steal_s():
    """CPU time the hypervisor took from this VM (all CPUs, /proc/stat ``steal``), s; None off Linux."""
    try:
        with open("/proc/stat") as f:
            return int(f.readline().split()[8]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


def _spec():
    spec = load_mre(MRE)
    spec["identifiers"] = [i for i in spec["identifiers"] if i["kind"] == "rls"]      # orders 3, 4, 5
    spec["mre"]["overrun_budget"] = 1.0        # measure every sample, never stop on overruns
    return spec


def _serve(priority):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    proc = subprocess.Popen([sys.executable, "-m", "pneusim.cli", "serve-rig", "--rig", "paper1-mre", "--port",
                             str(port), "--seed", "1", "--watchdog", "1.0", "--rt-priority", str(priority)],
                            stdout=subprocess.PIPE, text=True)
    print("\n" + proc.stdout.readline().strip())
    return proc, f"udp:127.0.0.1:{port}"


@pytest.fixture(scope="module")
def rig_servers():
    """Two rig servers: at SCHED_FIFO 40 (as serve-rig starts by default) and with normal scheduling."""
    procs = {}

    def address(sched):
        if sched not in procs:
            procs[sched] = _serve(DEFAULT_PRIORITY if sched == "fifo" else 0)
        return procs[sched][1]

    yield address
    for proc, _ in procs.values():
        proc.terminate()
        proc.wait(10)


@pytest.fixture(scope="module", autouse=True)
def table():
    yield
    if RESULTS:
        print(f"\nMRE loop, paper 1 (RLS orders 3, 4, 5), {DURATION_S:g} s at 1 ms on {os.cpu_count()} CPUs")
        print(f"  {'plant':5s} {'pacing':8s} {'sched':6s} {'late p50':>9s} {'p99':>8s} {'max':>8s} {'>Ts/2 %':>8s} "
              f"{'overruns':>8s} {'compute p50':>11s} {'p99':>7s} {'load':>9s} {'steal':>6s}  (ms)")
        for (plant, pacing, sched), r in RESULTS.items():
            print(f"  {plant:5s} {pacing:8s} {sched:6s} {r['late_p50_ms']:9.3f} {r['late_p99_ms']:8.3f} "
                  f"{r['late_max_ms']:8.2f} {r['late_half_percent']:8.3f} {r['overruns']:8d} {r['compute_p50_ms']:11.3f} "
                  f"{r['compute_p99_ms']:7.3f} {r['load_before']:4.2f}/{r['load_after']:4.2f} {r['steal_ms']:6.0f}  "
                  f"{r.get('udp', '')}")
        print("  steal: CPU time the hypervisor took from the VM during the case (both CPUs); under SCHED_FIFO the "
              "loop's remaining stalls follow it")
        lines = [f"Paper 1's loop (RLS orders 3, 4, 5), {DURATION_S:g} s at 1 ms each.", "",
                 "| plant | pacing | scheduling | lateness p50 / p99 / max | late > half a sample | overruns | "
                 "computation p50 / p99 | load before / after | steal | UDP |", "|---|---|---|---|---|---|---|---|---|---|"]
        lines += [f"| {plant} | {pacing} | {sched} | {r['late_p50_ms']:.3f} / {r['late_p99_ms']:.3f} / "
                  f"{r['late_max_ms']:.2f} ms | {r['late_half_percent']:.3f} % | {r['overruns']} | "
                  f"{r['compute_p50_ms']:.3f} / {r['compute_p99_ms']:.3f} ms | {r['load_before']:.2f} / "
                  f"{r['load_after']:.2f} | {r['steal_ms']:.0f} ms | {r.get('udp', '')} |"
                  for (plant, pacing, sched), r in RESULTS.items()]
        write_results("mre", "Mixed-reality loop timing", "\n".join(lines))
        sim = RESULTS.get(("sim", "realtime", "fifo"), {})
        if "order4_live_equals_fast" in sim:
            print(f"  order-4 model of the live sim run equals the fast run's: {sim['order4_live_equals_fast']}")
        for plant in ("sim", "udp"):
            for sched in ("fifo", "normal"):
                rt, sl = RESULTS.get((plant, "realtime", sched)), RESULTS.get((plant, "sleep", sched))
                if rt and sl and rt["late_p99_ms"] > 0:
                    print(f"  {plant} {sched}: lateness p99 sleep / realtime = {sl['late_p99_ms'] / rt['late_p99_ms']:.2f}")
            fi, no = RESULTS.get((plant, "realtime", "fifo")), RESULTS.get((plant, "realtime", "normal"))
            if fi and no and fi["late_half_percent"] > 0:
                print(f"  {plant} realtime: late > Ts/2 normal / fifo = {no['late_half_percent'] / fi['late_half_percent']:.1f}")


@pytest.mark.parametrize("plant, pacing, sched", CASES)
def test_mre_loop_live(benchmark, tmp_path, request, plant, pacing, sched):
    where = request.getfixturevalue("rig_servers")(sched) if plant == "udp" else "sim"
    spec = _spec()
    rt = RealtimeSettings() if sched == "fifo" else RealtimeSettings.off()
    load_before, steal_before = os.getloadavg()[0], _steal_s()

    def once():
        return run_mre(spec, tmp_path, plant=where, mode="realtime", duration_s=DURATION_S, report=False,
                       pacing=SleepPacing(0.001) if pacing == "sleep" else None, rt=rt)

    run = benchmark.pedantic(once, rounds=1, iterations=1)
    s, tm = run.summary, run.summary["timing"]
    assert s["samples"] == int(round(DURATION_S / 0.001)) and s["stop_reason"] == "completed"
    r = {"late_p50_ms": tm["lateness_s"]["p50"] * 1e3, "late_p99_ms": tm["lateness_s"]["p99"] * 1e3,
         "late_max_ms": tm["lateness_s"]["max"] * 1e3, "late_half_percent": tm["late_half_sample_percent"],
         "overruns": tm["overruns"], "compute_p50_ms": tm["compute_s"]["p50"] * 1e3,
         "compute_p99_ms": tm["compute_s"]["p99"] * 1e3, "load_before": load_before,
         "load_after": os.getloadavg()[0], "os": s["realtime_os"]["applied"],
         "steal_ms": (_steal_s() - steal_before) * 1e3 if steal_before is not None else float("nan")}
    for notice in s["realtime_os"]["notices"]:
        print("\n" + notice)
    if plant == "udp":
        pc = s["plant_counts"]
        r["udp"] = (f"lost {pc['lost']} late {pc['late']} command to read p50 {pc['rtt_s']['p50'] * 1e3:.3f} ms "
                    f"p99 {pc['rtt_s']['p99'] * 1e3:.3f} ms")
    if (plant, pacing, sched) == ("sim", "realtime", "fifo"):
        # the live model is the rehearsal's: the same run as fast as possible, same seed
        fast = run_mre(spec, tmp_path / "fast", plant="sim", mode="fast", duration_s=DURATION_S, report=False)
        live_tf = s["identified"]["RLS ARMA order 4"]["transfer_function"]
        r["order4_live_equals_fast"] = live_tf == fast.summary["identified"]["RLS ARMA order 4"]["transfer_function"]
        print(f"\norder 4, live:  {live_tf}\norder 4, fast:  "
              f"{fast.summary['identified']['RLS ARMA order 4']['transfer_function']}")
    RESULTS[(plant, pacing, sched)] = r
    benchmark.extra_info.update(r)
