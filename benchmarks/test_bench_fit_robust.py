"""The fit's robustness set, and a warm-started refit against a cold fit.

* ``test_robustness_set``: every recording of :func:`pneusim.fit.robustness.robustness_cases`
  (48 by default, ``PNEUSIM_ROBUST_N`` to change; rigs 30 % off their data sheets, both rigs, every
  experiment kind, open and closed loop, with and without pressures) is fitted from the data sheet;
  prints the share that reaches the noise level (normalised residual <= 1.1; target >= 95 %), the
  share of parameters whose truth lies within 3 sigma (target >= 90 %) and the time per fit, and
  writes one JSON line per case to ``PNEUSIM_ROBUST_OUT`` when set, and the table to
  ``docs/results/fit-robustness.md`` (``fit-robustness-N.md`` for another ``PNEUSIM_ROBUST_N``,
  ``-defaults-free`` appended when the smoothing velocity is not freed).  The free set is the seven defaults
  plus the friction smoothing velocity (:func:`pneusim.fit.robustness.fit_free`, see that module for
  why); ``PNEUSIM_ROBUST_FREE_SMOOTHING=0`` fits the seven defaults only.
* ``test_refit_warm_against_cold``: diagnosis refits a recording once per candidate effect.  The
  refit with a dead band switched on, warm-started from the nominal fit, against the same fit from
  the data sheet, in the same run (the effect model's kernels compiled beforehand for both).

    nice -n 10 pytest benchmarks/test_bench_fit_robust.py --benchmark-only -s
"""

import json
import os
import time

import numpy as np
import pytest

from pneusim.experiment import standard_experiment
from pneusim.fit import DEFAULT_FREE, EFFECT_FREE, fit_recording
from pneusim.fit.robustness import fit_free, make_case, robustness_cases, score
from pneusim.model import ActuatorModel, make_effect
from pneusim.rig import load_rig
from pneusim.simulate import simulate
from results_file import write_results


@pytest.mark.benchmark(group="fit-robustness")
def test_robustness_set(benchmark):
    specs = robustness_cases(int(os.environ.get("PNEUSIM_ROBUST_N", "48")))
    out_path = os.environ.get("PNEUSIM_ROBUST_OUT")
    free = fit_free(os.environ.get("PNEUSIM_ROBUST_FREE_SMOOTHING", "1") != "0")
    rows = []

    def run():
        for spec in specs:
            rig, truth, rec = make_case(spec)
            started = time.perf_counter()
            try:
                row = score(fit_recording(rec, rig, free=free, quiet=True), truth)
                row["z"] = {k: float(v) for k, v in row["z"].items()}
            except Exception as exc:  # a failed fit counts as not converged, and is reported
                row = {"error": f"{type(exc).__name__}: {exc}", "converged_to_noise": False,
                       "inside_3_sigma": 0, "parameters": len(DEFAULT_FREE)}
            row.update(name=spec.name, wall_s=time.perf_counter() - started)
            rows.append(row)
            print(f"{spec.name}: normalised residual {row.get('normalised_residual', float('nan')):.3f}, "
                  f"{row['inside_3_sigma']}/{row['parameters']} within 3 sigma, {row['wall_s']:.1f} s", flush=True)
            if out_path:
                with open(out_path, "a") as f:
                    f.write(json.dumps(row) + "\n")

    benchmark.pedantic(run, rounds=1, iterations=1)
    converged = np.mean([r["converged_to_noise"] for r in rows])
    coverage = sum(r["inside_3_sigma"] for r in rows) / sum(r["parameters"] for r in rows)
    seconds = np.array([r["wall_s"] for r in rows])
    print(f"\nrobustness set ({len(free)} free parameters): {len(rows)} recordings, {100 * converged:.0f} % reach the noise level "
          f"(target 95 %), truth within 3 sigma for {100 * coverage:.0f} % of the parameters (target 90 %), "
          f"{seconds.mean():.1f} s per fit (median {np.median(seconds):.1f} s, longest {seconds.max():.1f} s); "
          f"load {os.getloadavg()[0]:.1f}")
    benchmark.extra_info.update({"converged_share": float(converged), "coverage": float(coverage),
                                 "seconds_per_fit": float(seconds.mean())})
    inside = sum(r["inside_3_sigma"] for r in rows)
    lines = [f"{len(rows)} recordings, {len(free)} free parameters, each fitted from the data sheet.", "",
             "| measure | value | target |", "|---|---|---|",
             f"| reach the noise level (normalised residual <= 1.1) | {sum(r['converged_to_noise'] for r in rows)} / "
             f"{len(rows)} ({100 * converged:.0f} %) | 95 % |",
             f"| true values within 3 standard errors | {inside} / {sum(r['parameters'] for r in rows)} "
             f"({100 * coverage:.1f} %) | 90 % |",
             f"| time per fit, mean / median / longest | {seconds.mean():.1f} s / {np.median(seconds):.1f} s / "
             f"{seconds.max():.1f} s | |", "",
             "| recording | normalised residual | within 3 sigma | s |", "|---|---|---|---|"]
    for r in rows:
        residual = f"{r['normalised_residual']:.3f}" if "normalised_residual" in r else f"failed: {r['error']}"
        lines.append(f"| {r['name']} | {residual} | {r['inside_3_sigma']}/{r['parameters']} | {r['wall_s']:.1f} |")
    name = "fit-robustness" + ("" if len(specs) == 48 else f"-{len(specs)}") + ("" if len(free) > len(DEFAULT_FREE)
                                                                             else "-defaults-free")
    write_results(name, "How often the physical fit converges: the robustness set", "\n".join(lines))


@pytest.mark.benchmark(group="fit-refit")
def test_refit_warm_against_cold(benchmark):
    from pneusim.solver.sensitivity import _compiled_kernels

    rig = load_rig("paper2-enfield")
    true_rig = rig.with_params({"moving_mass_kg": 1.2 * rig["moving_mass_kg"],
                                "friction_coulomb_N": 0.9 * rig["friction_coulomb_N"]})
    exp = standard_experiment(true_rig, "pulses", 30.0, "open", seed=5)
    rec = simulate(true_rig, exp, [make_effect("valve_deadband", deadband_V=0.3)], seed=6).recording
    nominal = fit_recording(rec, rig, quiet=True)
    effects = [make_effect("valve_deadband")]
    free = list(DEFAULT_FREE) + list(EFFECT_FREE["valve_deadband"])
    _compiled_kernels(ActuatorModel(effects), tuple(free))     # compile once, for both
    times, results = {}, {}

    def run():
        for label, warm in (("cold", None), ("warm", nominal)):
            started = time.perf_counter()
            results[label] = fit_recording(rec, rig, effects, warm_start=warm, quiet=True)
            times[label] = time.perf_counter() - started

    benchmark.pedantic(run, rounds=1, iterations=1)
    line = "; ".join(f"{k}: {times[k]:.1f} s, normalised residual {results[k].normalised_residual:.3f}, dead band "
                     f"{results[k].estimates['valve_deadband.deadband_V']:.4f} V" for k in ("cold", "warm"))
    print(f"\nrefit with valve_deadband: {line} -> warm refit {times['cold'] / times['warm']:.1f}x faster "
          f"(nominal fit {nominal.solver['seconds']:.1f} s); load {os.getloadavg()[0]:.1f}")
    benchmark.extra_info.update({"cold_s": times["cold"], "warm_s": times["warm"]})
    assert results["warm"].converged_to_noise
