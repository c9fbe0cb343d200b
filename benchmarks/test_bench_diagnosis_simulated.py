"""Diagnosis of recordings made by pneusim's own simulator: every effect of the vocabulary once, and
controls, each on a rig drawn off its data sheet -- the recovery check beside the practice sets, on
recordings nobody tuned the method on.

    pytest benchmarks/test_bench_diagnosis_simulated.py --benchmark-only -s
    PNEUSIM_SIMDIAG_RIG=paper1-mre PNEUSIM_SIMDIAG_SEED=7 pytest benchmarks/test_bench_diagnosis_simulated.py ...

The rigs: every default free parameter within +-30 % of the data sheet, the critical pressure ratio in
0.22-0.40 and the friction smoothing velocity in 0.5-2 mm/s (:func:`pneusim.fit.robustness.draw_truth`,
the fit's robustness set).  The magnitudes: the middle of the ranges ``shared/practice2/answers.json``'s
manifest gives per rig (effects that change the recorded position clearly), each drawn within +-15 %
of it.  The experiments: closed-loop random steps, closed-loop multisine (paper 2) or pulses (paper 1),
and open-loop command doublets kept off the end stops by a pulse towards the middle
(:func:`pneusim.experiment.recentering_doublets`, as practice2's), in turn; heat transfer open loop only (closed loop hides it), pressures
recorded for every other case.  Prints and writes (``results/diagnosis-simulated-<rig>/score.md``, and
``docs/results/diagnosis-simulated-<rig>.md`` headed by the commit, machine, date and command) the
truth, the findings, the fitted effect parameters, the validation fit before and after, and the time.
"""

import os
import statistics
import time
from pathlib import Path

import numpy as np
import pytest

from pneusim.diagnosis import diagnose
from pneusim.experiment import recentering_doublets, standard_experiment
from pneusim.fit.robustness import draw_truth
from pneusim.model import make_effect
from pneusim.model.chamber import areas_m2
from pneusim.recording import write_recording
from pneusim.rig import load_rig
from pneusim.simulate import simulate
from results_file import write_results

HERE = Path(__file__).resolve().parent.parent
RIG = os.environ.get("PNEUSIM_SIMDIAG_RIG", "paper2-enfield")
SEED = int(os.environ.get("PNEUSIM_SIMDIAG_SEED", "11"))
DURATION_S = {"paper2-enfield": 60.0, "paper1-mre": 15.0}
#: ISO 6358 reference density, kg/m^3 (the valve's full flow is C p_supply rho_0)
RHO_0 = 1.185

#: the middle of practice2's manifest ranges, per rig
MIDDLE = {
    "paper2-enfield": {"leak_internal_frac": 0.125, "leak_external_frac": 0.05, "deadband_V": 0.375,
                       "offset_V": 0.25, "offset_V_open": 0.075, "spool_fn_Hz": 6.5, "delay_s": 0.0375,
                       "heat_tau_s": 0.065, "friction_factor_closed": 2.85, "friction_factor_open": 1.9,
                       "droop_conductance_ratio": 0.375, "droop_volume_m3": 2.5e-4, "load_constant_frac": 0.275,
                       "pdf_coefficient": 2.75},
    "paper1-mre": {"leak_internal_frac": 0.055, "leak_external_frac": 0.04, "deadband_V": 0.25,
                   "offset_V": 0.25, "offset_V_open": 0.035, "spool_fn_Hz": 13.0, "delay_s": 0.015,
                   "heat_tau_s": 0.065, "friction_factor_closed": 2.7, "friction_factor_open": 1.9,
                   "droop_conductance_ratio": 0.105, "droop_volume_m3": 4e-5, "load_constant_frac": 0.275,
                   "pdf_coefficient": 2.75},
}
EFFECTS = ("leakage", "valve_deadband", "valve_offset", "valve_dynamics", "transport_delay", "heat_transfer",
           "friction_asymmetry", "supply_pressure_droop", "external_load", "pressure_dependent_friction")
EXPERIMENTS = (("closed", "steps"), ("closed", None), ("open", "doublets"))


def _effect(name, rig, loop, rng):
    m = MIDDLE[RIG]
    vary = lambda x: float(x * rng.uniform(0.85, 1.15))  # noqa: E731
    full_flow = rig["valve_sonic_conductance_m3_per_s_Pa"] * rig["supply_Pa"] * RHO_0
    if name == "leakage":
        if rng.uniform() < 0.5:
            return make_effect(name, kind="internal", conductance_kg_per_s_Pa=vary(m["leak_internal_frac"]) * full_flow / 5e5)
        return make_effect(name, kind="external", chamber=str(rng.choice(["a", "b"])),
                           conductance_kg_per_s_Pa=vary(m["leak_external_frac"]) * full_flow / 5e5)
    if name == "valve_deadband":
        return make_effect(name, deadband_V=vary(m["deadband_V"]))
    if name == "valve_offset":
        return make_effect(name, offset_V=float(rng.choice([-1, 1])) * vary(m["offset_V" if loop == "closed" else "offset_V_open"]))
    if name == "valve_dynamics":
        return make_effect(name, natural_frequency_Hz=vary(m["spool_fn_Hz"]), damping=float(rng.uniform(0.6, 0.8)))
    if name == "transport_delay":
        return make_effect(name, delay_s=vary(m["delay_s"]))
    if name == "heat_transfer":
        return make_effect(name, time_constant_s=vary(m["heat_tau_s"]), wall_temperature_K=rig["supply_temperature_K"])
    if name == "friction_asymmetry":
        return make_effect(name, retract_factor=vary(m["friction_factor_closed" if loop == "closed" else "friction_factor_open"]))
    if name == "supply_pressure_droop":
        return make_effect(name, supply_volume_m3=vary(m["droop_volume_m3"]), regulator_Pa=rig["supply_Pa"],
                           supply_conductance_m3_per_s_Pa=vary(m["droop_conductance_ratio"]) * rig["valve_sonic_conductance_m3_per_s_Pa"])
    if name == "external_load":
        area_a, _, _ = areas_m2(rig["bore_m"], rig["rod_m"])
        full_force = (rig["supply_Pa"] - rig["atmosphere_Pa"]) * area_a
        return make_effect(name, kind="constant", force_N=float(rng.choice([-1, 1])) * vary(m["load_constant_frac"]) * full_force)
    if name == "pressure_dependent_friction":
        return make_effect(name, pressure_coefficient=vary(m["pdf_coefficient"]))
    raise ValueError(name)


def cases():
    """``(label, effect name or None, loop, kind, pressures, seed)`` of the set: the ten effects, then controls."""
    closed_second = "multisine" if RIG == "paper2-enfield" else "pulses"
    out = []
    for i, name in enumerate(EFFECTS + (None, None, None)):
        loop, kind = EXPERIMENTS[i % len(EXPERIMENTS)]
        kind = kind or closed_second
        if name == "heat_transfer":
            loop, kind = "open", "doublets"
        out.append((name or "control", name, loop, kind, i % 2 == 0, SEED * 100 + i))
    return out


def make_recording(folder, label, name, loop, kind, pressures, seed):
    rig = load_rig(RIG)
    rng = np.random.default_rng(seed)
    true_rig = rig.with_params(draw_truth(rig, seed))
    effects = [_effect(name, true_rig, loop, rng)] if name else []
    if loop == "open":   # an operator keeps an open-loop test off the end stops, as in practice2
        exp = recentering_doublets(true_rig, DURATION_S[RIG], seed=seed)
    else:
        exp = standard_experiment(true_rig, kind, DURATION_S[RIG], loop, seed=seed)
    rec = simulate(true_rig, exp, effects, seed=seed + 1, record_pressures=pressures).recording
    rec.metadata["rig"] = RIG
    path = Path(folder) / f"{label}-{loop}-{kind}{'-p' if pressures else ''}.csv"
    write_recording(rec, path)
    return path, effects


@pytest.mark.benchmark(group="diagnosis")
def test_diagnose_simulated_set(benchmark, tmp_path):
    out = HERE / "results" / f"diagnosis-simulated-{RIG}"
    out.mkdir(parents=True, exist_ok=True)
    rows = []

    def run():
        for label, name, loop, kind, pressures, seed in cases():
            path, effects = make_recording(tmp_path, label, name, loop, kind, pressures, seed)
            started = time.perf_counter()
            try:
                result = diagnose(path)
                found, error = result.effects, ""
                nominal, final = result.nominal["fit_percent"], result.final_fit_percent
                params = result.findings[0].parameters if result.findings else {}
            except Exception as exc:  # a failure is a row, and counts as a miss
                found, error, nominal, final, params = [], f"{type(exc).__name__}: {exc}", float("nan"), float("nan"), {}
            truth = effects[0].to_text() if effects else "none"
            ok = (found[:1] == [name]) if name else not [f for f in found if f != "other"]
            rows.append((path.name, truth, " ".join(found) or "none", params, nominal, final,
                         time.perf_counter() - started, ok, error))
            print(f"{path.name}: truth {truth}, found {' '.join(found) or 'none'} {params}, validation "
                  f"{nominal:.2f} -> {final:.2f} %, {rows[-1][6]:.0f} s{'' if ok else '  <-- MISS'} {error}", flush=True)

    benchmark.pedantic(run, rounds=1, iterations=1)
    effect_rows = [r for r in rows if r[1] != "none"]
    controls = [r for r in rows if r[1] == "none"]
    lines = [f"# Diagnosis of pneusim's own simulations ({RIG}, seed {SEED})", "",
             f"* true effect ranked first: {sum(r[7] for r in effect_rows)}/{len(effect_rows)}",
             f"* controls with a vocabulary effect claimed: {sum(not r[7] for r in controls)}/{len(controls)}",
             f"* median time per recording: {statistics.median(r[6] for r in rows):.0f} s", "",
             "| recording | truth | found | fitted parameters | nominal fit % | final fit % | s | ok |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        params = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in r[3].items())
        lines.append(f"| {r[0]} | `{r[1]}` | {r[2]} | {params} | {r[4]:.2f} | {r[5]:.2f} | {r[6]:.0f} | "
                     f"{'yes' if r[7] else 'NO'} {r[8]} |")
    (out / "score.md").write_text("\n".join(lines) + "\n")
    write_results(f"diagnosis-simulated-{RIG}", lines[0].lstrip("# "), "\n".join(lines[2:]))
    print("\n" + "\n".join(lines))
    assert rows
