"""The fit's robustness set: seeded recordings of rigs far from their data sheets.

One place for the recordings that the robustness benchmark (``benchmarks/test_bench_fit_robust.py``,
all of them) and the robustness test (``tests/pneusim/test_fit_robust.py``, the hardest kinds) fit.

Each case is a recording made by our simulator of a rig whose every default free parameter
(:data:`~pneusim.fit.DEFAULT_FREE`) is drawn uniformly within +-30 % of the data sheet, except the
valve's critical pressure ratio, drawn in 0.22-0.40, and whose friction smoothing velocity (not
freed by the fit, so the fit keeps the data sheet's 1 mm/s) is drawn in 0.5-2 mm/s.  The cases
cycle through both rigs, every experiment kind (``steps``, ``multisine``, ``pulses``) in open and
closed loop, with and without recorded chamber pressures; the draws come from the case's seed.

    from pneusim.fit.robustness import robustness_cases, make_case, score, fit_free
    for spec in robustness_cases(48):
        rig, truth, recording = make_case(spec)
        result = fit_recording(recording, rig, free=fit_free(True), quiet=True)
        print(spec.name, score(result, truth))

What defeats the default fit here (issue 9).  The friction smoothing velocity ``v_eps`` of
``tanh(v / v_eps)`` is not a numerical detail in a hold: a stuck piston creeps at
``v_eps atanh(F_net / F_s)``, so over a 1-4 s hold of a closed-loop step the recorded position
depends on it.  With the data sheet's 1 mm/s held fixed, the best the fit can do on closed-loop
random steps (no pressures, paper 2, started *at the truth*) ends at a normalised residual of 2.3
for a true 0.5 mm/s, 1.13 for 1.63 mm/s and 1.32 for 2 mm/s, with the static friction and the
Stribeck velocity pulled off to compensate.  Freed beside the seven defaults (``fit_free(True)``),
the case that ended at 2.64 from the data sheet reaches 1.00 with all eight truths within 1 sigma
(smoothing 1.638 mm/s against 1.63 true).  The second cause, seen on the issue's own recording
(smoothing equal to the fit's): stick-slip breakaways are locally unstable (the Stribeck drop is a
negative damping with an e-folding time of milliseconds), so a 50-sample segment spanning one has
huge sensitivities; the cost in (static friction, Stribeck velocity) is rippled by each mistimed
micro-slip and the trust region stops at "step tolerance" (pre-fit 3.11 there; 10-sample segments
1.49, still short of noise).  Two more causes were found on paper-2 open-loop steps without
pressures (``s5006``, 2.05 times noise even from the truth): the first segment's unmeasured start
state, estimated at the data sheet's parameters, sat in a wrong stick-slip basin (start velocity
-0.37 m/s against -0.087 m/s, 20-27 times noise on the first ten samples), and the model's piston
pressed 0.08 mm past the stop where the sensor reads at most the stroke (-1.4 times noise on
average at every sample at the stop).  The fitter now searches the first state again at the
pre-fit's parameters (:func:`.initial.better_first_state`) and compares the mean reading of a
saturating sensor (:func:`.shooting.expected_position_reading`): that case ends at 0.92 with all
seven default truths within 3 sigma, and seven of the eight hardest cases reach noise.

What still defeats it (stop 33): paper-2 open-loop recordings stick-slip from sample to sample through
every slow motion (the true velocity jumps between 0 and 0.1-0.15 m/s at 10 ms; ``s1030``: 52 % of the
samples below 1 mm/s), so a segment's residual depends on the phase of that oscillation.  Even from the
true parameters such a fit can stop above noise: started from the measured states, ``s1026`` (steps,
pressures recorded) ends at 1.08 after the trust region, two segments at 5 and 3 times noise in a
spurious stick-slip that a pressure sample's noise starts in the nearly empty chamber A; from the true
states it ends at 0.994.  Adopted: where both pressures are recorded and the pre-fit ends above noise,
a route through 10-sample segments (:data:`~pneusim.fit.stages.SHORT_SEGMENTS`), then the pre-fit's
own problem from its parameters with each segment starting from the measured or the carried state
(:func:`~pneusim.fit.initial.initial_starts`' ``choose_starts``), kept when clearly lower on that same
problem: ``s1026`` ends at 1.03 with 7 of 7 truths within 3 sigma (the set's recordings with pressures:
22/24 against 21/24).  Tried and not adopted: (1) the choice of segment starts everywhere (from the data
sheet without pressures it moved two paper-1 recordings from noise to 1.34 and 1.90); (2) 10-sample
segments as the pre-fit itself: short segments with free starts absorb a missing effect (a dead-band
recording's nominal pre-fit ends at 1.20 times noise instead of far above it, which diagnosis's
screening and the fit's "model lacks physics" rule rely on).  (3) Searching
the start states of the segments above noise at the fitted parameters (random perturbations, then the
trust region): ``s1026`` from 1.08 to 0.994 at the truth, but from fits tens of percent off only 1-10 %
of the residual: there the parameters' basin is the cause, not the states.  (4) A scan of the valve
conductance over 0.6-1.6 times the data sheet before the pre-fit, by the window's residual from
:func:`~pneusim.fit.initial.initial_starts` (on five closed-loop recordings without pressures its minimum
lies within 0.05 of the true factor, and ``s1017`` reaches noise from the true conductance alone): the
fit still ends at 4.03 on ``s1017``, and ``s1021`` went from 1.01 to 5.13.  Without pressures the data
sheet's friction starts the model oscillating where the recording creeps (or the reverse), and the fit
settles where a larger smoothing velocity damps the spurious oscillation (5-8 times the truth).

Stop 34 measured how chaotic those open-loop recordings are, on ``s1007`` (paper 2, multisine, no
pressures), whose fit ends at 1.65 times noise even when started at all eight true values.  At the true
parameters, segments started from the chained simulation fit their own samples at 0.8 times noise for the
first two segments and at 3-20 times it from the ninth on (the pre-fit window's start at 8.3): a start
state right to the integrator's tolerance leaves the recorded slip pattern within seconds.  Searching each
segment's hidden states afresh (:func:`~pneusim.fit.initial._hidden_state` with its grid, 19 s for 40
segments) brings the window to 0.87, and the pre-fit's continuation route (weight 10, then 1000) from the
chained starts to 0.85 with every parameter within 5 % but the smoothing velocity; the direct route, the
only one used without pressures, stops at 1.55.  Measured and not adopted, each on the failing cases and
where promising on the whole set: (5) the same hidden-state search (local, without the grid) for every
segment whose chained start fits its samples worse than twice the noise: ``s1007`` from the truth 1.65 ->
0.86, ``s1027`` 1.63 -> 1.03, ``s1006`` 1.45 -> 1.11, ``s1017`` 4.03 -> 2.68, but seven recordings that
reached noise no longer did (``s1013`` 3.04, ``s1021`` 5.49, ``s1022`` 1.73, ``s1026`` 1.26, ``s1029`` 1.22,
``s1041`` 19.3, ``s1042`` 2.00): 33 of the first 45 reach noise; (6) the continuation after the direct
pre-fit without pressures, from its end point or from its parameters with fresh starts: pre-fits lower
(``s1031`` 2.40 -> 1.10, ``s1027`` 2.17 -> 1.42), fits not (``s1027`` 1.63, ``s1031`` 1.12-1.17, ``s1017``
4.03, ``s1007`` 5.79): the window's residual was bought with open defects (``s1027``: 1.42 -> 1.70 on the
whole part with continuity weighted 1e4); (7) a homotopy in the smoothing velocity (fixed at 16, then 4
mm/s, then free): ``s1007`` 9.19, ``s1031`` 1.87, ``s1027`` 1.93; (8) starts screened by the window's residual
(32 quasi-random candidates within a factor 1.5, 0.11 s each on paper 1): ``s1017``'s two best had the
conductance within 9 % and fitted to 5.22 and 1.50; (9) SciPy's exact (dense) trust-region subproblem:
the benchmark's pre-fit 35 -> 23 evaluations (2.6 -> 2.0 s), but ``s1021`` 1.01 -> 6.12 and ``s1027`` 2.56;
(10) CVODES's error control on the sensitivities: the same 34 pre-fit evaluations, 4.8 -> 7.0 s, and
``s1027`` 1.95, ``s1017`` 3.03.

Stop 35: segment starts from an extended Kalman filter (:mod:`.tracking`).  At ``s1007``'s true parameters
the filter's states at the segment starts bring the window from 8.29 (chained) to 0.90 in 0.4 s, what the
grid search of every segment gave in 19 s.  At the data sheet's parameters they do not help (``s1007``
62.7 chained against 50-109 filtered, ``s1027`` 43.8 against 44-74): the model must be close first.  Adopted:
after a fit that ends above noise, every segment started from the filter's states at that fit's parameters,
then the continuation (:func:`~pneusim.fit.routes.tracked_route`).  ``s1027`` goes from 1.63 to 0.77 with
all seven truths within 3 sigma (all within 1.2 % of the truth); ``s1031`` 1.21 -> 1.17, ``s1017`` 4.03 ->
3.87; ``s1006`` (pressures recorded) is not lowered (1.34 against 1.31), and ``s1007`` and ``s1030`` are not
tried (every pre-fit more than 5 times above noise).  Measured and not adopted: the same route in the
pre-fit, from the pre-fit's parameters (``s1007`` from the truth 1.55 -> 1.95, from the data sheet 5.6 ->
6.0; ``s1030`` 6.55 -> 5.86, not clearly lower); each segment starting from the better of its fitted and
its filtered state (``s1031`` 1.11, ``s1006`` 1.30: no better); the trust region's ``x_scale="jac"`` again
(the benchmark's pre-fit 35 -> 21 evaluations, but ``s1002`` 1.00 -> 8.08, as at stop 31).

Stop 36: the filter's innovations as the cost (:mod:`.prediction_error`). The five that still failed were four
paper-2 open-loop multisine recordings (every one of that kind in the set) and ``s1017``. Along the line from
``s1007``'s data-sheet values to its truth the filter's negative log-likelihood falls monotonically to its
minimum at the truth (whitened innovations 30.5, 21.8, 4.0, 0.90 at 0, 0.5, 0.9, 1 of the way), and least
squares on the whitened innovations from the data sheet, with the process noise lowered in turn, end within 1
% of every truth on ``s1030``, ``s1007`` and ``s1017`` in 10-20 s. Adopted: after every other stage, a fit
still above noise runs that from its start, then the tracked route from its parameters, kept when lower
(:func:`~pneusim.fit.routes.prediction_error_route`): ``s1007`` 5.79 -> 0.87 and ``s1030`` 9.74 -> 0.99 with 7
of 7 truths within 3 sigma, ``s1031`` 1.17 -> 0.96 (4 of 7), ``s1006`` 1.44 -> 1.105 (7 of 7; 1.02 over
position and pressures together, the position alone just above 1.1), ``s1017`` not lowered (its filter ends at
3.7 times its noise level in a basin with the Stribeck velocity at 5 times the truth; once, with the filter's
gain and covariance propagated in another order, it ended at 0.99 within 1 % of every truth: the innovations
are smooth near the truth, but at the data sheet's values the filter can lose track of the piston, and where
it does depends on the integrator's rounding). The set: 46 of 48 reach noise, 97.0 % of the truths within 3
sigma. Measured and not adopted: the same process noise on unmeasured pressures as on the other states
(``s1007``: static and Coulomb friction 1.39 and 1.83 of the truth); a hundredth of it on *measured* pressures
too (``s1030``: the filter lost track, 2.36); a broader first stage (process noise 0.1 and 0.03 first:
``s1017``, ``s1006`` and ``s1031`` all in wrong basins with the smoothing velocity 0.2-5.7 times the truth);
the smoothing velocity freed in the broad stages too (``s1006``: 2.15, the smoothing at 10 times the truth);
another tracked round while the position alone is above noise (``s1006``: 1.019, then 1.025); a second
prediction-error start from the best fit's parameters (``s1017`` 3.85, ``s5000`` 6.48 times the innovations'
noise level); a window of 1000 or 4000 samples for ``s1017`` (2.48 and 3.57, both in wrong basins).

Stop 37, speed (the issue's 5x against SciPy's peer): the pre-fit's trust region is most of the benchmark
fit (35 evaluations, 2.8-3.0 s of 4.0-4.2 s), and its count is set by the parameters, not the segment
states: from the true parameters it takes 4 evaluations, from the data sheet with the true states 24, from
the data sheet 35.  Its first step goes far (the Stribeck velocity to 2.4 and the mass to 0.64 of the truth,
SciPy's first trust radius is 21 in the scaled variables) and the next 17 creep back.  Measured and not
adopted, on the benchmark's recording and ``s1001``, ``s1005``, ``s1013``, ``s1021``, ``s1033``: the pre-fit at
``rtol`` 1e-5 (2.6 s against 3.2 s) or 1e-4 (1.2 s, but the window ends at 1.79 times noise: the integration
error dominates); the first trust radius capped at 0.1-3 (2.2-2.7 s; SciPy has no public option for it);
the parameters boxed within a factor of 1.5 of the start first, then freed (``s1013`` 1.00 -> 1.99, ``s1021``
0.98 -> 4.40); a 500-sample pre-fit first, then the 2000-sample one from its parameters (the benchmark's
pre-fit 0.98 -> 2.50, ``s1013`` 1.00 -> 2.00, ``s1021`` 0.98 -> 1.46); the segment states fitted alone at
the start's parameters first (5 or 9 evaluations, then 24 or 16: 2.6 s against 3.2 s once, the other time
ending at 2.52 times noise).  Adopted after
the pre-fit instead: Gauss-Newton steps on the constrained problem where the whole part's trust region
ends at noise (:func:`~pneusim.fit.stages.settled`), the same fits as IPOPT's (19 of the set's 48 residuals
moved, none by more than 4e-4; 46 of 48 at noise, 97.0 % within 3 sigma as before), 5.2 -> 4.0 s on the benchmark.

Stop 38, speed again: the pre-fit's evaluation count is chaotic in the solver's options, and the benchmark's
recording is one draw.  The exact trust-region subproblem with the Jacobian's column scaling took the
benchmark's pre-fit from 35 to 17 evaluations (the fit 4.1 -> 2.9 s), but over 41 of the set's recordings the
median pre-fit went from 15 to 20 evaluations (``s1004``: 9 -> 61-65 with either option alone), ``s1004`` ended
at 1.052 with 3 of 7 truths within 3 sigma and ``s1031`` at 1.106; the exact subproblem alone: 23 evaluations
on the benchmark, ``s1004`` 61; the column scaling alone: 21, ``s1027`` 3 of 7.  The first trust radius set
through SciPy's public interface (the variables measured from the start, where SciPy's first radius is 1, and
``x_scale`` the radius): 56, 24 and 50 evaluations for radii 0.3, 1 and 3.  The pre-fit at ``rtol`` 1e-5 or
3e-6 (each evaluation 35 % or 15 % cheaper): 41 and 43 evaluations.  The pre-fit's Jacobian as a dense matrix
for LSMR (the same problem, rounding apart): 40 evaluations and slower.  Segments of 25 or 100 samples in the
pre-fit: 1.51 and 2.66 times noise.  A bounded Levenberg-Marquardt with geodesic acceleration (Transtrum and
Sethna's remedy for narrow curved valleys; prototype, Levenberg's or Marquardt's damping): 37-81 evaluations,
2.7-3.8 times noise.  Adopted instead, for robustness: the pre-fit's window moves to where the piston moves
when it rests through the first one (:meth:`~pneusim.fit.setup.FitSetup.prefit_start`).

Stop 39, the cost of an evaluation instead of their count: the augmented sensitivity corrector
(:class:`~pneusim.solver.sensitivity.SensitivitySimulator`) is the default, with one fresh trust region
in the pre-fit after a stall above noise (:func:`~pneusim.fit.stages.prefit`).  The whole set, two fits at a
time: 46 of 48 at noise (as before), 323 of 336 truths within 3 sigma (326 before: ``s1012`` 7 -> 3 of 7 at
1.018 -> 1.063 times noise, a basin the staggered corrector missed; ``s1031`` 4 -> 5), median 2.3 s against
3.9 s per fit, mean 13.3 s against 18.6 s.  The corrector alone: 10.2 s mean and 2.0 s median, the same 323,
but the fit benchmark's pre-fit stalled at 4.14 times noise (16.2 s in all, the fresh start's case; 2.8 s
with it).  The fresh start costs the set's pre-fits 1814 evaluations against 1415 (``s1002``, pressures
recorded, stalls in both pre-fit routes: 48 -> 80 evaluations, 4.7 -> 28.3 s to the same answer).
Measured and not adopted: up to three fresh starts while each lowers the residual by 2 % (320 of 336:
``s1027`` 7 -> 3, ``s1031`` 5 -> 6; mean 13.9 s); the
pre-fit at ``rtol`` 1e-5 with the augmented corrector (28 of the 49 pre-fits within 1.1 times noise against
33); a 1000-sample pre-fit window (32, median 19 evaluations against 16); the direct route as a continuation
through continuity weights 100 and 1000 (staggered corrector: 74 evaluations on the benchmark against 35,
more on most); the states' trust-region scale ``x_scale`` = 100 (staggered: the benchmark's pre-fit stops at
2.59 times noise, the set's median pre-fit 19 evaluations against 14).

Stop 40, the same arithmetic in less time (the block solve, one model kernel, the state's norm, whole-window
residuals; ``benchmarks/test_bench_fit.py``): all 48 residuals equal stop 39's to the last digit, median 2.0 s,
mean 12.0 s (two at a time).  Measured and not adopted: the runs without sensitivities stepping as those with
them (the augmented memory's norm the state's own, divided by the state count, with undiluted tolerances,
and the state's memory setting its Newton matrix up at every step: the same states to the bit with and
without, so IPOPT's objective values and gradients would come from one integration); every fit's path moves,
and the benchmark's pre-fit drew more evaluations (2.95 s, 4.4 times faster than SciPy against 5.6).
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
