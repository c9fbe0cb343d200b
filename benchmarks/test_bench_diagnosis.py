"""Mismatch diagnosis over a whole practice set, scored against its answers; one command gives the table.

    pytest benchmarks/test_bench_diagnosis.py --benchmark-only -s
    PNEUSIM_DIAGNOSIS_SET=../shared/practice pytest benchmarks/test_bench_diagnosis.py --benchmark-only -s

Every recording of the set (default ``../shared/practice2``) is diagnosed on the sweep executor
(``PNEUSIM_DIAGNOSIS_WORKERS`` processes, default 1: the machine is shared) and scored against
``answers.json`` -- which only this benchmark reads, after the diagnosis:

* **top-1** -- effect cases (exactly one effect) whose first finding is the true effect;
* **two-effect cases** -- the first finding is one of the two;
* **false findings on controls** -- controls with any vocabulary effect claimed (``other`` allowed);
* **median validation fit** before (nominal) and after (final) on the effect cases;
* **median time** per recording, and its ratio to the nominal fit alone measured in the same run
  (the peer: what any fit-based diagnosis has to pay at least).

The table is written to ``results/diagnosis-<set>/score.md`` beside the per-recording results and
``summary.csv``, and to ``docs/results/diagnosis-<set>.md`` with the commit, machine, date and command
(:mod:`results_file`).  ``PNEUSIM_DIAGNOSIS_LIMIT=N`` diagnoses the first N files only (a quick look);
``PNEUSIM_DIAGNOSIS_RIG=paper2-enfield`` only the recordings whose ``rig`` metadata names that rig
(the table then goes to ``results/diagnosis-<set>-<rig>/``).
"""

import json
import os
import statistics
import subprocess
from pathlib import Path

import pytest

from results_file import write_results

HERE = Path(__file__).resolve().parent.parent
SET = Path(os.environ.get("PNEUSIM_DIAGNOSIS_SET", HERE.parent / "shared" / "practice2"))
RIG = os.environ.get("PNEUSIM_DIAGNOSIS_RIG")
LIMIT = int(os.environ.get("PNEUSIM_DIAGNOSIS_LIMIT", "0") or 0)


def _load():
    answers = SET / "answers.json"
    if not answers.is_file():
        pytest.skip(f"no practice set with answers at {SET}")
    files = sorted(SET.glob("*.csv"))
    if RIG:   # the recordings' own metadata chooses, not the answers
        from pneusim.recording import read_recording
        from pneusim.rig import known_rig_names

        if RIG not in known_rig_names():
            pytest.fail(f"PNEUSIM_DIAGNOSIS_RIG={RIG!r} is not a known rig; expected one of "
                        f"{', '.join(known_rig_names())}", pytrace=False)
        files = [f for f in files if read_recording(f).rig == RIG]
    return files[:LIMIT] if LIMIT else files, json.loads(answers.read_text())["cases"]


def score(rows, cases) -> dict:
    """The score table of the module docstring from the summary rows and the answers."""
    single, double, controls = [], [], []
    for r in rows:
        truth = [e["effect"] for e in cases[r["recording"]]["effects"]]
        found = r["findings"].split() if r["status"] == "ok" and r["findings"] != "none" else []
        vocabulary = [f for f in found if f != "other"]
        entry = {"recording": r["recording"], "truth": truth, "found": found, "status": r["status"],
                 "nominal": r["nominal_fit_percent"], "final": r["final_fit_percent"], "seconds": r["seconds"],
                 "error": r["error"]}
        if not truth:
            entry["ok"] = r["status"] == "ok" and not vocabulary
            controls.append(entry)
        elif len(truth) == 1:
            entry["ok"] = bool(found) and found[0] == truth[0]
            single.append(entry)
        else:
            entry["ok"] = bool(found) and found[0] in truth
            entry["both"] = set(truth) <= set(found)
            double.append(entry)
    effect_cases = single + double
    fits_before = [e["nominal"] for e in effect_cases if e["nominal"] is not None]
    fits_after = [e["final"] for e in effect_cases if e["final"] is not None]
    times = [e["seconds"] for e in single + double + controls if e["seconds"] is not None]
    return {
        "top1": (sum(e["ok"] for e in single), len(single)),
        "two_effect_first": (sum(e["ok"] for e in double), len(double)),
        "two_effect_both": (sum(e.get("both", False) for e in double), len(double)),
        "false_on_controls": (sum(not e["ok"] for e in controls), len(controls)),
        "median_fit_before": statistics.median(fits_before) if fits_before else float("nan"),
        "median_fit_after": statistics.median(fits_after) if fits_after else float("nan"),
        "median_seconds": statistics.median(times) if times else float("nan"),
        "failed": sum(e["status"] != "ok" for e in single + double + controls),
        "cases": single + double + controls,
    }


def _table(s, load, ratio) -> str:
    def frac(p):
        return f"{p[0]}/{p[1]} ({100 * p[0] / p[1]:.0f} %)" if p[1] else "n/a"

    lines = [f"# Diagnosis score on `{SET.name}`" + (f" (recordings of `{RIG}` only)" if RIG else ""), "",
             "| measure | value |", "|---|---|",
             f"| true effect ranked first (one-effect cases) | {frac(s['top1'])} |",
             f"| first finding one of the two (two-effect cases) | {frac(s['two_effect_first'])} |",
             f"| both effects found (two-effect cases) | {frac(s['two_effect_both'])} |",
             f"| controls with a vocabulary effect claimed | {frac(s['false_on_controls'])} |",
             f"| median validation fit, effect cases, nominal | {s['median_fit_before']:.2f} % |",
             f"| median validation fit, effect cases, final | {s['median_fit_after']:.2f} % |",
             f"| median time per recording | {s['median_seconds']:.0f} s |",
             f"| median time / median nominal fit time (same run) | {ratio:.1f} |",
             f"| recordings that failed | {s['failed']} |",
             f"| machine load during the run (uptime) | {load} |", "",
             "| recording | truth | found | nominal fit % | final fit % | s | ok |", "|---|---|---|---|---|---|---|"]
    for e in s["cases"]:
        nominal = f"{e['nominal']:.2f}" if e["nominal"] is not None else "-"
        final = f"{e['final']:.2f}" if e["final"] is not None else "-"
        lines.append(f"| {e['recording']} | {' + '.join(e['truth']) or 'none'} | {' '.join(e['found']) or 'none'} | "
                     f"{nominal} | {final} | {e['seconds']:.0f} | {'yes' if e['ok'] else 'NO'} |")
    return "\n".join(lines) + "\n"


@pytest.mark.benchmark(group="diagnosis")
def test_diagnose_practice_set(benchmark):
    from pneusim.diagnosis.batch import diagnose_many

    files, cases = _load()
    out = HERE / "results" / (f"diagnosis-{SET.name}" + (f"-{RIG}" if RIG else ""))
    workers = int(os.environ.get("PNEUSIM_DIAGNOSIS_WORKERS", "1"))
    rows = benchmark.pedantic(lambda: diagnose_many(files, out, workers=workers, report=True, progress=True),
                              rounds=1, iterations=1)
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip().split("load average:")[-1].strip()
    nominal_times = []
    for r in rows:
        if r["result"] is not None:
            nominal_times.append(r["result"]["timing"]["nominal_fit_s"])
    s = score(rows, cases)
    ratio = s["median_seconds"] / statistics.median(nominal_times) if nominal_times else float("nan")
    table = _table(s, load, ratio)
    (out / "score.md").write_text(table)
    print("\n" + table)
    name = f"diagnosis-{SET.name}" + (f"-{RIG}" if RIG else "") + (f"-first-{LIMIT}" if LIMIT else "")
    title, _, body = table.partition("\n")
    write_results(name, title.lstrip("# "), f"{len(rows)} recordings, {workers} at a time.\n{body}")
    assert s["failed"] < len(rows)
