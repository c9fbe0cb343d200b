"""Mismatch diagnosis over a whole practice set, scored against its answers; one command gives the table.

    pytest benchmarks/test_bench_diagnosis.py --benchmark-only -s
    PNEUSIM_DIAGNOSIS_SET=../shared/practice pytest benchmarks/test_bench_diagnosis.py --benchmark-only -s
    PNEUSIM_DIAGNOSIS_SET=../shared/practice3 PNEUSIM_DIAGNOSIS_HALF=odd PNEUSIM_DIAGNOSIS_WORKERS=2 \
        pytest benchmarks/test_bench_diagnosis.py --benchmark-only -s

Every recording of the set (default ``../shared/practice2``) is diagnosed on the sweep executor
(``PNEUSIM_DIAGNOSIS_WORKERS`` processes, default 1: the machine is shared) and scored against
``answers.json`` -- which only this benchmark reads, after the diagnosis.  An answer lists the concealed
vocabulary effects, and physics outside the vocabulary as ``{"effect": "other", "truth": NAME}``:

* **per-effect recall** -- concealed vocabulary effects named, over all of them;
* **cases fully right** -- the vocabulary names found are exactly the concealed ones, and ``other`` is
  reported exactly where physics outside the vocabulary is concealed;
* **false vocabulary names** -- names found that are not concealed, in all and on the controls;
* **``other`` on out-of-vocabulary cases** -- and ``other`` where nothing outside the vocabulary is;
* **top-1** -- one-effect cases whose first finding is the true effect; **two-effect cases** -- the first
  finding is one of the two, both found (the measures the earlier tables give);
* **false findings on controls** -- controls with any vocabulary effect claimed (``other`` allowed);
* **median validation fit** before (nominal) and after (final) on the effect cases without physics outside
  the vocabulary;
* **median and worst time** per recording, the CPU time of the worst, the median of each stage's time, and
  the ratio of the median time to the nominal fit alone measured in the same run; per recording also the time
  budget used (counted in model work, the same on every machine).

The table is written to ``results/diagnosis-<set>/score.md`` beside the per-recording results and
``summary.csv``, and to ``docs/results/diagnosis-<set>.md`` with the commit, machine, date and command
(:mod:`results_file`).  ``PNEUSIM_DIAGNOSIS_LIMIT=N`` diagnoses the first N files only (a quick look);
``PNEUSIM_DIAGNOSIS_SEVERAL=1`` runs ``--several-effects``, ``=0`` ``--no-several-effects``;
``PNEUSIM_DIAGNOSIS_RIG=paper2-enfield`` only the recordings whose ``rig`` metadata names that rig
(the table then goes to ``results/diagnosis-<set>-<rig>/``); ``PNEUSIM_DIAGNOSIS_HALF=odd`` or ``even``
only the recordings whose number is odd or even (``diagnosis-<set>-odd``): develop on one half, score the
other once.
"""

import json
import math
import os
import re
import statistics
import subprocess
from pathlib import Path

import pytest

from results_file import write_results

HERE = Path(__file__).resolve().parent.parent
SET = Path(os.environ.get("PNEUSIM_DIAGNOSIS_SET", HERE.parent / "shared" / "practice2"))
RIG = os.environ.get("PNEUSIM_DIAGNOSIS_RIG")
LIMIT = int(os.environ.get("PNEUSIM_DIAGNOSIS_LIMIT", "0") or 0)
HALF = os.environ.get("PNEUSIM_DIAGNOSIS_HALF", "")


def _number(path: Path) -> int:
    found = re.findall(r"(\d+)", path.stem)
    return int(found[-1]) if found else 0


def _load():
    answers = SET / "answers.json"
    if not answers.is_file():
        pytest.skip(f"no practice set with answers at {SET}")
    if HALF not in ("", "odd", "even"):
        pytest.fail(f"PNEUSIM_DIAGNOSIS_HALF={HALF!r}: expected odd or even", pytrace=False)
    files = sorted(SET.glob("*.csv"))
    if HALF:
        files = [f for f in files if _number(f) % 2 == (1 if HALF == "odd" else 0)]
    if RIG:   # the recordings' own metadata chooses, not the answers
        from pneusim.recording import read_recording
        from pneusim.rig import known_rig_names

        if RIG not in known_rig_names():
            pytest.fail(f"PNEUSIM_DIAGNOSIS_RIG={RIG!r} is not a known rig; expected one of "
                        f"{', '.join(known_rig_names())}", pytrace=False)
        files = [f for f in files if read_recording(f).rig == RIG]
    return files[:LIMIT] if LIMIT else files, json.loads(answers.read_text())["cases"]


def _median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else float("nan")


def _entry(row, case) -> dict:
    """One recording scored: its truth (vocabulary names, and whether physics outside the vocabulary is
    concealed), what was found, and whether the answer is fully right."""
    truth_all = [e["effect"] for e in case["effects"]]
    truth = [e for e in truth_all if e != "other"]
    oov = [e.get("truth", "other") for e in case["effects"] if e["effect"] == "other"]
    found = row["findings"].split() if row["status"] == "ok" and row["findings"] not in ("", "none") else []
    vocabulary = [f for f in found if f != "other"]
    result = row.get("result") or {}
    return {"recording": row["recording"], "truth": truth, "oov": oov, "found": found, "status": row["status"],
            "nominal": row["nominal_fit_percent"], "final": row["final_fit_percent"], "seconds": row["seconds"],
            "cpu": (result.get("timing") or {}).get("cpu_s"), "budget": (result.get("timing") or {}).get("budget_s"),
            "timing": result.get("timing") or {},
            "run_status": result.get("status", ""), "error": row["error"],
            "named": len(set(truth) & set(vocabulary)), "false": sorted(set(vocabulary) - set(truth)),
            "other": "other" in found,
            "fully_right": row["status"] == "ok" and set(vocabulary) == set(truth) and ("other" in found) == bool(oov)}


def score(rows, cases) -> dict:
    """The score table of the module docstring from the summary rows and the answers."""
    entries = [_entry(r, cases[r["recording"]]) for r in rows]
    single = [e for e in entries if len(e["truth"]) == 1 and not e["oov"]]
    double = [e for e in entries if len(e["truth"]) == 2 and not e["oov"]]
    controls = [e for e in entries if not e["truth"] and not e["oov"]]
    oov = [e for e in entries if e["oov"]]
    for e in single:
        e["ok"] = bool(e["found"]) and e["found"][0] == e["truth"][0]
    for e in double:
        e["ok"] = bool(e["found"]) and e["found"][0] in e["truth"]
    for e in controls:
        e["ok"] = e["status"] == "ok" and not e["false"]
    for e in entries:
        e.setdefault("ok", e["fully_right"])
    in_vocabulary = [e for e in entries if e["truth"] and not e["oov"]]
    times = [e["seconds"] for e in entries if e["seconds"] is not None]
    stages = sorted({k for e in entries for k in e["timing"] if k.endswith("_s") and k not in ("total_s", "cpu_s", "budget_s")})
    return {
        "recall": (sum(e["named"] for e in entries), sum(len(e["truth"]) for e in entries)),
        "fully_right": (sum(e["fully_right"] for e in entries), len(entries)),
        "false_names": sum(len(e["false"]) for e in entries),
        "false_names_controls": sum(len(e["false"]) for e in controls),
        "other_on_oov": (sum(e["other"] for e in oov), len(oov)),
        "other_elsewhere": (sum(e["other"] for e in entries if not e["oov"]), len(entries) - len(oov)),
        "top1": (sum(e["ok"] for e in single), len(single)),
        "two_effect_first": (sum(e["ok"] for e in double), len(double)),
        "two_effect_both": (sum(set(e["truth"]) <= set(e["found"]) for e in double), len(double)),
        "false_on_controls": (sum(not e["ok"] for e in controls), len(controls)),
        "median_fit_before": _median([e["nominal"] for e in in_vocabulary]),
        "median_fit_after": _median([e["final"] for e in in_vocabulary]),
        "median_fit_after_all": _median([e["final"] for e in entries if not e["oov"]]),
        "median_seconds": _median(times),
        "worst_seconds": max(times) if times else float("nan"),
        "worst_cpu": max((e["cpu"] for e in entries if e["cpu"] is not None), default=float("nan")),
        "stage_medians": {k: _median([e["timing"].get(k) for e in entries]) for k in stages},
        "unfinished": sum(e["run_status"] not in ("", "complete") for e in entries),
        "failed": sum(e["status"] != "ok" for e in entries),
        "cases": single + double + [e for e in entries if len(e["truth"]) > 2 and not e["oov"]] + oov + controls,
    }


def _frac(p):
    return f"{p[0]}/{p[1]} ({100 * p[0] / p[1]:.0f} %)" if p[1] else "n/a"


def _table(s, load, ratio) -> str:
    title = f"# Diagnosis score on `{SET.name}`" + (f" ({HALF}-numbered recordings)" if HALF else "")
    title += f" (recordings of `{RIG}` only)" if RIG else ""
    stages = ", ".join(f"{k[:-2].replace('_', ' ')} {v:.0f} s" for k, v in s["stage_medians"].items())
    lines = [title, "",
             "| measure | value |", "|---|---|",
             f"| per-effect recall (concealed vocabulary effects named) | {_frac(s['recall'])} |",
             f"| cases fully right | {_frac(s['fully_right'])} |",
             f"| false vocabulary names, in all | {s['false_names']} |",
             f"| false vocabulary names, on controls | {s['false_names_controls']} |",
             f"| `other` on out-of-vocabulary cases | {_frac(s['other_on_oov'])} |",
             f"| `other` on the other cases | {_frac(s['other_elsewhere'])} |",
             f"| true effect ranked first (one-effect cases) | {_frac(s['top1'])} |",
             f"| first finding one of the two (two-effect cases) | {_frac(s['two_effect_first'])} |",
             f"| both effects found (two-effect cases) | {_frac(s['two_effect_both'])} |",
             f"| controls with a vocabulary effect claimed | {_frac(s['false_on_controls'])} |",
             f"| median validation fit, effect cases without outside physics, nominal | {s['median_fit_before']:.2f} % |",
             f"| median validation fit, effect cases without outside physics, final | {s['median_fit_after']:.2f} % |",
             f"| median validation fit, all cases without outside physics, final | {s['median_fit_after_all']:.2f} % |",
             f"| median time per recording | {s['median_seconds']:.0f} s |",
             f"| worst time (wall), worst CPU time | {s['worst_seconds']:.0f} s, "
             + (f"{s['worst_cpu']:.0f} s |" if not math.isnan(s['worst_cpu']) else "- |"),
             f"| median time by stage | {stages or 'n/a'} |",
             f"| median time / median nominal fit time (same run) | {ratio:.1f} |",
             f"| recordings stopped by the time budget | {s['unfinished']} |",
             f"| recordings that failed | {s['failed']} |",
             f"| machine load during the run (uptime) | {load} |", "",
             "| recording | truth | found | nominal fit % | final fit % | s | CPU s | budget s | fully right |",
             "|---|---|---|---|---|---|---|---|---|"]
    for e in s["cases"]:
        nominal = f"{e['nominal']:.2f}" if e["nominal"] is not None else "-"
        final = f"{e['final']:.2f}" if e["final"] is not None else "-"
        truth = " + ".join(e["truth"] + [f"other ({n})" for n in e["oov"]]) or "none"
        cpu = f"{e['cpu']:.0f}" if e["cpu"] is not None else "-"
        budget = f"{e['budget']:.0f}" if e["budget"] is not None else "-"
        seconds = f"{e['seconds']:.0f}" if e["seconds"] is not None else "-"
        status = "" if e["run_status"] in ("", "complete") else f" ({e['run_status']})"
        lines.append(f"| {e['recording']} | {truth} | {' '.join(e['found']) or 'none'}{status} | {nominal} | "
                     f"{final} | {seconds} | {cpu} | {budget} | {'yes' if e['fully_right'] else 'NO'} |")
    return "\n".join(lines) + "\n"


@pytest.mark.benchmark(group="diagnosis")
def test_diagnose_practice_set(benchmark):
    from pneusim.diagnosis.batch import diagnose_many

    files, cases = _load()
    suffix = (f"-{RIG}" if RIG else "") + (f"-{HALF}" if HALF else "")
    out = HERE / "results" / f"diagnosis-{SET.name}{suffix}"
    workers = int(os.environ.get("PNEUSIM_DIAGNOSIS_WORKERS", "1"))
    several = {"": None, "0": False}.get(os.environ.get("PNEUSIM_DIAGNOSIS_SEVERAL", ""), True)
    rows = benchmark.pedantic(lambda: diagnose_many(files, out, workers=workers, report=True, progress=True,
                                                    several_effects=several),
                              rounds=1, iterations=1)
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip().split("load average:")[-1].strip()
    nominal_times = [r["result"]["timing"]["nominal_fit_s"] for r in rows if r["result"] is not None]
    s = score(rows, cases)
    ratio = s["median_seconds"] / statistics.median(nominal_times) if nominal_times else float("nan")
    table = _table(s, load, ratio)
    (out / "score.md").write_text(table)
    print("\n" + table)
    name = f"diagnosis-{SET.name}{suffix}" + (f"-first-{LIMIT}" if LIMIT else "")
    title, _, body = table.partition("\n")
    write_results(name, title.lstrip("# "), f"{len(rows)} recordings, {workers} at a time.\n{body}")
    assert s["failed"] < len(rows)
