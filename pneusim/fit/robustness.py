"""The fit's robustness set: seeded recordings of rigs far from their data sheets.

One place for the recordings that the robustness benchmark (``benchmarks/test_bench_fit_robust.py``,
all of them) and the robustness tests (``tests/pneusim/fit/test_fit_robust.py``, the hardest kinds and a
few cases by name) fit.

Each case is a recording made by our simulator of a rig whose every default free parameter
(:data:`~pneusim.fit.DEFAULT_FREE`) is drawn uniformly within +-30 % of the data sheet, except the
valve's critical pressure ratio, drawn in 0.22-0.40, and whose friction smoothing velocity (not
freed by the default fit, which keeps the data sheet's 1 mm/s) is drawn in 0.5-2 mm/s.  The cases
cycle through both rigs, every experiment kind (``steps``, ``multisine``, ``pulses``) in open and
closed loop, with and without recorded chamber pressures; the draws come from the case's seed.  The
set is fitted with the smoothing velocity freed beside the defaults (:func:`fit_free`): over a hold a
stuck piston creeps at a rate set by it, so the recorded position depends on it.

    from pneusim.fit.robustness import robustness_cases, make_case, score, fit_free
    for spec in robustness_cases(48):
        rig, truth, recording = make_case(spec)
        result = fit_recording(recording, rig, free=fit_free(True), quiet=True)
        print(spec.name, score(result, truth))

What each stage of the fit changed on this set, and what was measured on it and not adopted, is in the
decision records (``docs/decisions/0022`` for the set itself, and the records it links).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..experiment import standard_experiment
from ..rig import Rig, load_rig
from .parameters import DEFAULT_FREE

__all__ = ["CaseSpec", "robustness_cases", "hardest_cases", "make_case", "score", "fit_free", "SMOOTHING",
           "DURATION_S"]

#: recording length per rig, s (paper 2 samples at 10 ms, paper 1 at 1 ms)
DURATION_S = {"paper2-enfield": 30.0, "paper1-mre": 6.0}
#: the drawn ranges: relative half-width for the default free parameters, absolute ranges otherwise
RELATIVE_SPREAD = 0.3
CRITICAL_PRESSURE_RATIO = (0.22, 0.40)
SMOOTHING_VELOCITY_M_PER_S = (0.5e-3, 2e-3)

RIGS = ("paper2-enfield", "paper1-mre")
KINDS = ("steps", "multisine", "pulses")
LOOPS = ("closed", "open")


@dataclass(frozen=True)
class CaseSpec:
    """One recording of the set: which rig, experiment, loop, whether pressures are recorded, seed."""

    rig_name: str
    kind: str
    loop: str
    pressures: bool
    seed: int

    @property
    def name(self) -> str:
        return f"{self.rig_name}-{self.kind}-{self.loop}-{'p' if self.pressures else 'x'}-s{self.seed}"


def robustness_cases(n: int = 48, seed: int = 0) -> list[CaseSpec]:
    """``n`` cases cycling through rig x kind x loop x pressures (24 combinations), seeds from ``seed``."""
    combos = list(itertools.product(RIGS, KINDS, LOOPS, (True, False)))
    return [CaseSpec(*combos[i % len(combos)], seed=seed + 1000 + i) for i in range(n)]


def hardest_cases(n: int = 8, seed: int = 0) -> list[CaseSpec]:
    """The kinds where stick-slip matters most: closed-loop random steps and pulses (a hold at every
    step, the piston sticking and slipping), and open-loop steps, mostly without pressures, on both
    rigs.  Seeds distinct from :func:`robustness_cases`'."""
    kinds = [("paper2-enfield", "steps", "closed", False), ("paper2-enfield", "steps", "closed", True),
             ("paper1-mre", "steps", "closed", False), ("paper1-mre", "steps", "closed", True),
             ("paper2-enfield", "pulses", "closed", False), ("paper1-mre", "pulses", "closed", False),
             ("paper2-enfield", "steps", "open", False), ("paper1-mre", "steps", "open", False)]
    return [CaseSpec(*kinds[i % len(kinds)], seed=seed + 5000 + i) for i in range(n)]


def draw_truth(rig: Rig, seed: int) -> dict[str, float]:
    """The true parameters of a case (SI units): see the module docstring for the ranges."""
    rng = np.random.default_rng(seed)
    truth = {}
    for name in DEFAULT_FREE:
        if name == "valve_critical_pressure_ratio":
            truth[name] = float(rng.uniform(*CRITICAL_PRESSURE_RATIO))
        else:
            truth[name] = float(rig[name] * rng.uniform(1.0 - RELATIVE_SPREAD, 1.0 + RELATIVE_SPREAD))
    truth["friction_smoothing_velocity_m_per_s"] = float(rng.uniform(*SMOOTHING_VELOCITY_M_PER_S))
    if truth["friction_coulomb_N"] > truth["friction_static_N"]:
        # a Stribeck curve rises from Coulomb to static friction: keep the draw physical
        truth["friction_static_N"], truth["friction_coulomb_N"] = truth["friction_coulomb_N"], truth["friction_static_N"]
    return truth


def make_case(spec: CaseSpec):
    """``(data-sheet rig, truth dict, recording)`` of a case, with the rig files' sensor noise."""
    from ..simulate import simulate

    rig = load_rig(spec.rig_name)
    truth = draw_truth(rig, spec.seed)
    true_rig = rig.with_params(truth)
    experiment = standard_experiment(true_rig, spec.kind, DURATION_S[spec.rig_name], spec.loop, seed=spec.seed)
    sim = simulate(true_rig, experiment, seed=spec.seed + 7, record_pressures=spec.pressures)
    return rig, truth, sim.recording


#: the friction smoothing velocity: drawn in the set; freeing it beside the defaults is the fix measured here
SMOOTHING = "friction_smoothing_velocity_m_per_s"


def fit_free(free_smoothing: bool) -> list[str]:
    """The free set the set is fitted with: :data:`DEFAULT_FREE`, and the smoothing velocity when asked."""
    return list(DEFAULT_FREE) + ([SMOOTHING] if free_smoothing else [])


def score(result, truth: dict[str, float]) -> dict:
    """Normalised residual, whether the fit reached noise, and the truth's z-score per default free
    parameter (``z_smoothing`` too when the smoothing velocity was freed)."""
    # a standard error that is not finite (a direction the data did not constrain) or zero covers
    # nothing: z = inf, outside 3 sigma (dividing by inf gave z = 0, and such a fit counted 7 of 7)
    z = {name: _z(p, truth[name]) for name, p in result.parameters.items() if name in DEFAULT_FREE}
    return {"normalised_residual": result.normalised_residual, "converged_to_noise": result.converged_to_noise,
            "z": z, "inside_3_sigma": sum(abs(v) <= 3.0 for v in z.values()), "parameters": len(z),
            "seconds": float(result.solver["seconds"]),
            **({"z_smoothing": _z(result.parameters[SMOOTHING], truth[SMOOTHING])}
               if SMOOTHING in result.parameters else {})}


def _z(p, true_value: float) -> float:
    """The truth's z-score under estimate ``p``; inf where its standard error is not finite and positive."""
    return float((p.estimate - true_value) / p.std) if 0 < p.std < np.inf else float("inf")
