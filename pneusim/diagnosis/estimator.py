"""The diagnosis as an estimator with swappable stages: :class:`Diagnosis` and :class:`DiagnosisStages`.

``Diagnosis(effects=..., ...).fit(recording)`` runs, in order:

1. **nominal fit** -- the rig's free parameters (:data:`pneusim.fit.DEFAULT_FREE`) fitted to the estimation
   part (the first 70 %); the last 30 % validates and is never fitted;
2. **locate** (:mod:`.locate`) -- windows where the residual of the fitted nominal model exceeds the sensor
   noise, tagged with signal and operating condition;
3. **signatures** (:mod:`.signatures`) -- the vocabulary's signatures as numbers;
4. **screen** -- by how far the nominal fit is from the recording (:func:`.rules.screening_route`): not at all
   where its validation error leaves no refit room to pass the keep test; around the nominal optimum where it
   ends within :data:`~.rules.MODEL_SHORT` times the noise (:mod:`.around_nominal`); from the data sheet,
   every candidate pre-fitted on the window where the residual is largest, where it ends farther above
   (:mod:`.from_data_sheet`);
5. **jointly** (:mod:`.window_sets`) -- far above noise, where no candidate alone explains the screening's window:
   the leading effects pre-fitted together there in pairs, the best pair fitted whole and kept against the nominal
   model, then drop-one (8) and the search on top of it (7); where the best is a single effect or the pair fails,
   the one-effect-first confirmation:
   **confirm** -- the leading candidates, one per look-alike family, then their look-alikes, fitted whole
   (warm from the nominal fit, or from the data sheet) and kept only when they pass the keep test
   (:func:`.rules.passes_test`: an information criterion on the estimation part *and* a validation fit improved
   by more than noise explains);
6. **delay scan** (:mod:`.delay`) -- a kept transport delay that leads, or comes close, estimated by refits
   (a delay has no gradient);
7. **findings** (:mod:`.findings`) -- the kept candidate with the best validation fit first (its fit with the
   rescue routes where one from the data sheet skipped them and ends above noise: :func:`.refits.rescued`),
   then more effects on top of it, one at a time, each screened and tested with the findings before it present;
8. **drop-one** (:func:`.findings.drop_one`) -- each finding tested with all the others present, a look-alike
   that only helped while something else was missing dropped;
9. **other** (:mod:`.other`) -- where the model with every finding (the nominal model where there is none) still
   leaves a residual well above noise, an ``other`` finding: where, under which conditions, what it looks like,
   and which vocabulary effects came closest and why they failed.  Before it is said, the findings' fit gets the
   fit's rescue routes where it skipped them (:meth:`Diagnosis._before_other`).

Step 7 is first the one-effect-first search: a second effect among the candidates the first round kept or set
aside.  Where its findings leave the model above noise (:func:`.other.above_noise`: a residual above noise on the
estimation part and room on the validation part for a refit to pass the keep test), the several-effects search
goes on from them: every vocabulary variant not yet refitted on top is screened on top, up to
:data:`~.rules.MAX_FINDINGS_SEVERAL` findings; then 8 (where it added a finding) and 9's ``other`` after the
findings.  The time budget scales with the nominal fit's cost (:func:`.rules.default_budget_s`).
``several_effects=True`` runs the several-effects search from the first finding on, under
:data:`~.rules.TIME_BUDGET_S`; ``False`` never goes on (``other`` only where nothing was kept, no budget unless one
is given).

Every fit and screening after the nominal fit first asks the time budget (:mod:`.budget`): one that would end
past it is not started, and the diagnosis returns what it has, its ``status`` naming the step refused.

Each step is a field of :class:`DiagnosisStages`, and so are the fits, screenings and the keep test the
steps call; a step reads and writes one :class:`~.run.DiagnosisRun`.  The thresholds are in :mod:`.rules`.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import FitError, PneusimError
from ..fit import prefit_recording
from ..fit.setup import rig_of
from ..fit.threads import one_blas_thread
from ..recording import Recording, read_recording
from ..rig import Rig
from .around_nominal import confirm_around_nominal, screen_around_nominal
from .candidates import candidate_list, polished_costs, screen
from .delay import scan_found_delay, scan_kept_delay, screened_delays
from .budget import Budget, gated_stages
from .findings import add_findings, drop_one, joint_finding, more_findings, rank_by_contribution, refreshed
from .from_data_sheet import confirm_from_data_sheet, mismatch_window, one_start_each, screen_from_data_sheet
from .locate import episodes, locate_mismatch, named_states
from .other import above_noise, other_finding, unexplained
from .refits import (estimation_cost, fit_from_data_sheet, fit_nominal, noise_levels, refit, rescued,
                     with_rescue_routes)
from .result import DiagnosisResult
from .rules import (AT_NOISE_ON_WINDOW, MAX_FINDINGS, MAX_FINDINGS_SEVERAL, MAX_LOOKALIKES, MAX_REFITS, MIN_SAMPLES, MODEL_SHORT,
                    SCREEN_SAMPLES, SET_EXPLAINS_WINDOW, SET_FIT_SHARE, SET_SHRINK, TIME_BUDGET_S, VALIDATION_FRACTION, VALIDATION_FRACTION_RANGE,
                    VALIDATION_MOTION_NOISE, WINDOW_SAMPLES,
                    default_budget_s, keep_test_text, noise_floor_points, passes_test, screening_route,
                    validation_room)
from .run import DiagnosisRun, NominalBaseline
from .signatures import compute_signatures
from .window_sets import fit_best_set, search_sets

__all__ = ["Diagnosis", "DiagnosisStages"]


@dataclass(frozen=True)
class DiagnosisStages:
    """The stages of :class:`Diagnosis`, each a callable, today's by default.  Pass others to study or test one
    stage alone, e.g. ``DiagnosisStages(refit=stand_in)`` runs the method on stand-in refits.

    The steps, in order (see :mod:`.estimator`):

    nominal_fit : ``(recording, rig, validation_fraction) -> FitResult`` (:func:`.refits.fit_nominal`)
    locate : ``(recording, rig, states, noise) -> (windows, info)`` (:func:`.locate.locate_mismatch`)
    signatures : ``(recording, rig, states, velocity) -> dict`` (:func:`.signatures.compute_signatures`)
    screen_around_nominal, confirm_around_nominal : near noise (:mod:`.around_nominal`)
    screen_from_data_sheet, confirm_from_data_sheet : far above noise (:mod:`.from_data_sheet`)
    delay_scan : ``(run) -> None`` (:func:`.delay.scan_kept_delay`)
    findings : ``(run, kept) -> (findings, final fit)`` (:func:`.findings.add_findings`)
    more_findings : ``(run, findings, final fit) -> (findings, final fit)``, the several-effects search on top of
        the one-effect-first search's findings (:func:`.findings.more_findings`)
    drop_one : ``(run, findings, final fit) -> (findings, final fit)`` (:func:`.findings.drop_one`)
    other : ``(run, final fit, duration_s, search_ended) -> Finding or None`` (:func:`.other.other_finding`)

    What the steps call:

    screen : ``(fit, recording, candidate or None, noise, samples) -> dict`` (:func:`.candidates.screen`)
    polished_costs : ``(fit, recording, noise, samples) -> {evaluations: cost}`` (:func:`.candidates.polished_costs`)
    prefit : :func:`pneusim.fit.prefit_recording`, the screening from the data sheet's pre-fit
    refit : ``(recording, rig, effects, warm, start_values=None) -> FitResult`` (:func:`.refits.refit`)
    fit : ``(recording, rig, effects, validation_fraction, start_values) -> FitResult``, a whole fit from the
        data sheet (:func:`.refits.fit_from_data_sheet`)
    rescue : ``(recording, rig, fit, validation_fraction) -> FitResult``, ``fit`` fitted again as it was started,
        with the fit's rescue routes (:func:`.refits.with_rescue_routes`)
    keep_test : ``(cost0, cost1, n, k, fit0, fit1, floor) -> (kept, threshold, reason)`` (:func:`.rules.passes_test`)
    """

    nominal_fit: Callable = fit_nominal
    locate: Callable = locate_mismatch
    signatures: Callable = compute_signatures
    screen_around_nominal: Callable = screen_around_nominal
    confirm_around_nominal: Callable = confirm_around_nominal
    screen_from_data_sheet: Callable = screen_from_data_sheet
    confirm_from_data_sheet: Callable = confirm_from_data_sheet
    delay_scan: Callable = scan_kept_delay
    findings: Callable = add_findings
    more_findings: Callable = more_findings
    drop_one: Callable = drop_one
    other: Callable = other_finding
    screen: Callable = screen
    polished_costs: Callable = polished_costs
    prefit: Callable = prefit_recording
    refit: Callable = refit
    fit: Callable = fit_from_data_sheet
    rescue: Callable = with_rescue_routes
    keep_test: Callable = passes_test


def _name(recording) -> str:
    return Path(str(recording.source or "recording")).name


def _load(recording, rig) -> tuple[Recording, Rig]:
    if not isinstance(recording, Recording):
        recording = read_recording(recording)
    return recording, rig_of(recording, rig)


def _check_input(recording: Recording, rig: Rig, validation_fraction: float) -> int:
    """The estimation part's length; refuses (one sentence) a recording too short to diagnose, a validation
    fraction out of range, or a validation part where the piston does not move."""
    name = _name(recording)
    n = recording.n_samples
    if n < MIN_SAMPLES:
        raise PneusimError(f"{name}: {n} samples are too short to diagnose (at least {MIN_SAMPLES}: the fit needs an "
                           f"estimation part and a validation part it never sees)")
    low, high = VALIDATION_FRACTION_RANGE
    if not low <= validation_fraction <= high:
        raise PneusimError(f"validation fraction must be in [{low:g}, {high:g}], got {validation_fraction}")
    n_est = int(round(n * (1.0 - validation_fraction)))
    noise = noise_levels(recording, rig)
    y = recording.position_m[n_est:]
    span = float(np.nanmax(y) - np.nanmin(y))
    least = VALIDATION_MOTION_NOISE * noise["position_m"]
    if not span > least:
        raise PneusimError(f"{name}: the piston moves only {span * 1e3:.3f} mm in the validation window "
                           f"{recording.time_s[n_est]:.2f}-{recording.time_s[-1]:.2f} s (at least "
                           f"{least * 1e3:.3f} mm, {VALIDATION_MOTION_NOISE:g} times the sensor noise, are needed to "
                           "score a model there)")
    return n_est


def _on_top(candidates: list, variants: dict) -> dict:
    """The candidates a search on top of the findings screens, by label: each screened effect's best variant,
    and every data-sheet start of an effect the first round did not screen (:func:`.from_data_sheet.one_start_each`)."""
    out = {c.label: c for _, c, _ in variants.values()}
    out.update({c.label: c for c in one_start_each(candidates) if c.name not in variants})
    return out


def _search_ended(budget: Budget, findings: list, kept: list, max_findings: int) -> str | None:
    """Why no more vocabulary effects were added, in words (for the ``other`` finding); None where the search
    did not end because nothing passed the test -- the time budget stopped it, or ``max_findings`` were
    modelled -- and what is left is then not known to be outside the vocabulary."""
    if budget.stopped is not None or len(findings) >= max_findings:
        return None
    return "no vocabulary effect passed the test" + (" on top of the findings" if kept else "")


def _ranking(ranked: list, variants: dict) -> str:
    return ", ".join(f"{k} ({variants[k][0]:.0f})" for k in ranked[:5])


class Diagnosis:
    """Diagnose what physics the nominal model leaves out of a recording (see :mod:`.estimator` for the steps).

    The constructor only stores the options (see :func:`~pneusim.diagnosis.diagnose` for each); :meth:`fit`
    diagnoses one recording.  ``stages`` (:class:`DiagnosisStages`) holds the stage callables.

    Examples
    --------
    >>> result = Diagnosis(effects=["leakage"]).fit("run.csv")                       # doctest: +SKIP
    >>> study = Diagnosis(stages=DiagnosisStages(keep_test=my_test)).fit("run.csv")   # doctest: +SKIP
    """

    def __init__(self, *, effects=None, validation_fraction: float = VALIDATION_FRACTION,
                 max_refits: int = MAX_REFITS, max_lookalikes: int = MAX_LOOKALIKES, max_findings: int | None = None,
                 screen_samples: int | None = None, progress: bool = False, several_effects: bool | None = None,
                 time_budget_s: float | None = None, stages: DiagnosisStages = DiagnosisStages()):
        self.effects, self.validation_fraction = effects, validation_fraction
        self.several_effects = several_effects
        if max_findings is None:
            max_findings = MAX_FINDINGS_SEVERAL if several_effects else MAX_FINDINGS
        if time_budget_s is None and several_effects is not None:
            time_budget_s = TIME_BUDGET_S if several_effects else math.inf
        #: seconds, counted in model work (:mod:`.budget`); None: set once the nominal fit's cost is known (:func:`.rules.default_budget_s`)
        self.time_budget_s = time_budget_s
        self.max_refits, self.max_lookalikes, self.max_findings = max_refits, max_lookalikes, max_findings
        self.screen_samples, self.progress, self.stages = screen_samples, progress, stages

    def _say(self, name: str, message: str) -> None:
        if self.progress:
            print(f"diagnose: {name}: {message}", file=sys.stderr, flush=True)

    @one_blas_thread
    def fit(self, recording, rig=None) -> DiagnosisResult:
        """Diagnose ``recording`` (a :class:`~pneusim.recording.Recording` or a path) on ``rig`` (default: the
        recording's ``rig`` metadata); raises :class:`~pneusim.errors.PneusimError` like
        :func:`~pneusim.diagnosis.diagnose`."""
        started, cpu_started = time.perf_counter(), time.process_time()
        budget = Budget(math.inf if self.time_budget_s is None else self.time_budget_s)
        recording, rig = _load(recording, rig)
        name = _name(recording)
        candidate_list(rig, recording.sample_time_s, self.effects)   # an unknown effect is refused before any work
        _check_input(recording, rig, self.validation_fraction)
        nominal = self._nominal_fit(recording, rig, name, budget)                             # 1. nominal fit
        t_nominal = time.perf_counter() - started
        nominal_s = budget.used()
        if self.time_budget_s is None:
            budget.seconds = default_budget_s(nominal_s)
        stages = gated_stages(self.stages, budget, nominal_s)
        noise = noise_levels(recording, nominal.rig)
        states = named_states(nominal)
        windows, _ = self.stages.locate(recording, nominal.rig, states, noise)                # 2. locate
        signatures = self.stages.signatures(recording, nominal.rig, states, states["velocity_m_per_s"])  # 3.
        candidates = candidate_list(rig, recording.sample_time_s, self.effects,
                                    screened_delays(signatures, recording.sample_time_s))
        self._say(name, f"nominal validation fit {nominal.fit_percent:.2f} %, {len(windows)} mismatch window(s); "
                        f"screening {len(candidates)} candidates")
        run = self._run(recording, nominal, noise, name, stages)
        t_started = time.perf_counter()
        route, ranked, variants, measure = self._screen(run, candidates, signatures)         # 4. screen
        t_screen = time.perf_counter() - t_started
        run.on_top = _on_top(candidates, variants)
        joint = self._joint(run, name, budget) if route == "from the data sheet" else None   # 5. jointly, or
        if joint is not None:
            findings, final = joint
            kept = [f.effect for f in findings]
            t_first = t_on_top = time.perf_counter()
            search = "several effects, found jointly"
        else:
            self._confirm(run, route, ranked, variants, measure)                              # 5. confirm
            stages.delay_scan(run)                                                            # 6. delay scan
            t_first = time.perf_counter()
            kept = run.kept_by_fit()
            findings, final = stages.findings(run, kept) if kept else ([], nominal)           # 7. findings
            several = self.several_effects
            search = "several effects" if several else "one effect first"
            if several is None and findings and above_noise(final, run.noise, run.baseline.floor):
                findings, final, several = self._go_on(run, findings, final, name)
                search = "one effect first, then several"
            t_on_top = time.perf_counter()
            if several:
                findings, final = run.stages.drop_one(run, findings, final)                   # 8. drop-one
        t_drop_one = time.perf_counter()
        duration_s = float(recording.time_s[-1] - recording.time_s[0])
        findings, final, ended = self._before_other(run, budget, findings, kept, final)
        other = run.stages.other(run, final, duration_s, ended) if ended is not None else None  # 9. other
        findings += [other] if other is not None else []
        basis = run.baseline
        result = DiagnosisResult(
            recording=name, rig=nominal.rig.name,
            validation={"t_start_s": float(recording.time_s[nominal.n_estimation]),
                        "t_end_s": float(recording.time_s[-1])},
            nominal={"fit_percent": basis.fit0, "parameters": nominal.estimates},
            mismatch=windows, findings=findings, final_fit_percent=final.fit_percent,
            final_parameters={k: final.estimates[k] for k in nominal.estimates if k in final.estimates},
            episodes=episodes(windows, duration_s), status=budget.status, search=search,
            candidates=[run.trials[k] for k in ranked] + [t for k, t in run.trials.items() if k not in ranked],
            test=keep_test_text(basis.floor, basis.fit0, validation_room(basis.fit0, basis.floor)),
            seconds=time.perf_counter() - started,
            timing={"nominal_fit_s": t_nominal, "screening_s": t_screen,
                    "refits_s": time.perf_counter() - started - t_nominal - t_screen,
                    "first_finding_s": t_first - t_started - t_screen, "on_top_s": t_on_top - t_first,
                    "drop_one_s": t_drop_one - t_on_top, "window_sets_s": run.window_sets_s,   # within first_finding_s
                    "rescue_s": sum(r["seconds"] for r in run.rescues),   # within the stages that asked for them
                    "cpu_s": time.process_time() - cpu_started,    # this process's: both fit threads
                    "budget_s": budget.used()},                    # the work counted, in the budget's seconds
            window_sets=[w.to_dict() for w in run.window_sets], rescues=list(run.rescues),
            nominal_fit=nominal, final_fit=final, signatures=signatures,
            fits={k: v[0] for k, v in run.refits.items()})
        self._say(name, f"findings {', '.join(result.effects) or 'none'}; final fit {final.fit_percent:.2f} % "
                        f"({result.seconds:.0f} s)")
        return result

    @staticmethod
    def _before_other(run: DiagnosisRun, budget: Budget, findings: list, kept: list, final):
        """9, first: why the search ended (:func:`_search_ended`; None where ``other`` is not said: the budget
        stopped it, or the one-effect-first search kept something) and, where ``other`` may be said, the
        findings' fit ``final`` with the fit's rescue routes where it skipped them and leaves physics unexplained
        (:func:`.refits.rescued`).  Returns ``(findings, final, ended)``.

        Why: a right set of findings stuck above noise on a recording too chaotic for the shooting problem would
        otherwise be reported with ``other``."""
        if findings and not run.several_effects:
            return findings, final, None   # the one-effect-first search says ``other`` only where nothing was kept
        ended = _search_ended(budget, findings, kept, run.max_findings)
        if ended is None or not findings:
            return findings, final, ended
        fit = rescued(run, final, lambda f: unexplained(f, run.noise, run.baseline.floor)[0], "before other")
        if fit is not final:
            findings, final = refreshed(findings, fit), fit
        return findings, final, _search_ended(budget, findings, kept, run.max_findings)

    def _go_on(self, run: DiagnosisRun, findings: list, final, name: str):
        """7, continued: the one-effect-first search's ``findings`` (their fit ``final``) leave the model above
        noise, and the several-effects search goes on from them (:func:`.findings.more_findings`), up to
        :data:`~.rules.MAX_FINDINGS_SEVERAL` findings, within what is left of the budget.  Returns ``(findings,
        final, added)``, ``added`` whether it added a finding (drop-one then tests them all)."""
        run.several_effects, run.max_findings = True, max(self.max_findings, MAX_FINDINGS_SEVERAL)
        n_before = len(findings)
        self._say(name, f"{', '.join(f.effect for f in findings)} leave(s) the model above noise "
                        f"(final fit {final.fit_percent:.2f} %): searching for more effects on top")
        findings, final = run.stages.more_findings(run, findings, final)
        return findings, final, len(findings) > n_before

    def _pair_to_fit(self, window_sets: list, name: str):
        """The best of ``window_sets`` where it is a set of two or more that brings the window within
        :data:`~.rules.SET_EXPLAINS_WINDOW` times noise and below :data:`~.rules.SET_SHRINK` of the best single
        effect's objective (its ``outcome`` says why where it is not); else None."""
        best = window_sets[0] if window_sets else None
        if best is None or len(best.candidates) < 2:
            return None
        if best.normalised_objective > SET_EXPLAINS_WINDOW:
            best.outcome = (f"not fitted: leaves the window {best.normalised_objective:.3g} times noise, above "
                            f"{SET_EXPLAINS_WINDOW:g}")
            self._say(name, f"the best set, {best.label}, leaves the window {best.normalised_objective:.3g} times "
                            f"noise (above {SET_EXPLAINS_WINDOW:g}): too little explained to choose the physics there")
            return None
        single = min((w for w in window_sets if len(w.candidates) == 1), default=None,
                     key=lambda w: w.normalised_objective)
        if single is not None and best.normalised_objective > SET_SHRINK * single.normalised_objective:
            best.outcome = (f"not fitted: {best.normalised_objective:.3g} times noise on the window, not "
                            f"{SET_SHRINK:g} of the best single effect's ({single.label}, "
                            f"{single.normalised_objective:.3g})")
            self._say(name, f"the best set, {best.label}, ends a hair below {single.label} alone on the window: "
                            f"one effect first")
            return None
        return best

    def _joint(self, run: DiagnosisRun, name: str, budget: Budget | None = None):
        """5, where no effect alone explains the screening's window: sets of the window's leading effects pre-fitted
        together there (:func:`.window_sets.search_sets`); where the best is a set of two or more, it is fitted
        whole and kept against the nominal model (:func:`.window_sets.fit_best_set`: where it ends far above noise,
        its other variants too), each member is tested with the others present (8, drop-one), their fit gets the
        rescue routes where it skipped them and ends above noise (:func:`.refits.rescued`), the findings ranked by
        what each adds with the others present, and the search goes on on top of them where they leave the model
        above noise (7).  Returns ``(findings, final
        fit)``, or None where the one-effect-first confirmation is to run instead (a single effect explains the
        window, the best set is a single effect, leaves the window above :data:`~.rules.SET_EXPLAINS_WINDOW` times
        noise or above :data:`~.rules.SET_SHRINK` of the best single effect's objective, or its whole fit failed the
        keep test or did not end within :data:`~.rules.SET_FIT_SHARE` of the budget left, the rest of which is
        then the confirmation's)."""
        window = run.window
        singles = [pre for _, pre in (window.singles.values() if window else ()) if pre is not None]
        if not (window and window.shows_mismatch and singles
                and min(pre.normalised_residual for pre in singles) > AT_NOISE_ON_WINDOW):
            return None
        max_effects = (run.max_findings if self.several_effects is False
                       else max(run.max_findings, MAX_FINDINGS_SEVERAL))
        self._say(name, "no effect alone explains the mismatch window: sets of the leading effects pre-fitted "
                        "together there")
        budget = budget if budget is not None else Budget()
        used, started = budget.used(), time.perf_counter()
        run.window_sets = search_sets(run, window.singles, window.options, max_effects)
        run.window_sets_s = time.perf_counter() - started
        best = self._pair_to_fit(run.window_sets, name)
        if best is None:
            # pre-fits that choose no pair are not charged to the one-effect-first search after them (a pair fitted
            # whole is charged)
            budget.refund(used)
            return None
        self._say(name, f"the set that explains the window best: {best.label} "
                        f"({best.normalised_objective:.3g} times noise there)")
        with budget.share(SET_FIT_SHARE):
            best, out = fit_best_set(run, run.window_sets, window.base.normalised_objective)
        if out is None or not out[2]:
            return None
        fit, _, _ = out
        run.joint = best
        run.several_effects, run.max_findings = True, max_effects
        for c in best.candidates:
            run.trials[c.name].kept = True
            run.refitted_on_top.add(c.label)
        findings = [joint_finding(c.name, fit, run.baseline.fit0, run.trials[c.name]) for c in best.candidates]
        findings, final = run.stages.drop_one(run, findings, fit)                             # 8. drop-one
        final = scan_found_delay(run, final)                                                  # 6. a delay
        final = rescued(run, final, lambda f: above_noise(f, run.noise, run.baseline.floor), "pair found jointly")
        findings = refreshed(findings, final)
        if len(findings) < run.max_findings and above_noise(final, run.noise, run.baseline.floor):
            n_before = len(findings)
            self._say(name, f"{', '.join(f.effect for f in findings)} leave(s) the model above noise "
                            f"(final fit {final.fit_percent:.2f} %): searching for more effects on top")
            findings, final = run.stages.more_findings(run, findings, final)                  # 7. on top
            if len(findings) > n_before:
                findings, final = run.stages.drop_one(run, findings, final)
        return rank_by_contribution(run, findings, final), final

    def _nominal_fit(self, recording, rig, name: str, budget: Budget):
        """1. The nominal fit (``stages.nominal_fit``); a recording it cannot start on, or whose nominal fit
        alone runs past the time budget (nothing can be judged without it), is refused in one sentence."""
        self._say(name, "nominal fit")
        with budget.deadline() as deadline:
            try:
                return self.stages.nominal_fit(recording, rig, self.validation_fraction)
            except PneusimError as exc:
                if deadline.reached:
                    raise FitError(f"{name}: the nominal fit alone ran past the diagnosis's time budget of "
                                   f"{budget.seconds:.0f} s (give a larger --time-budget)") from None
                raise FitError(f"{name}: the nominal fit failed on this recording: {exc}") from None

    def _run(self, recording, nominal, noise: dict, name: str, stages) -> DiagnosisRun:
        """The run every later step reads and writes, with the nominal baseline the keep test compares with."""
        cost0, n_res = estimation_cost(nominal, noise)
        floor = noise_floor_points(recording, nominal.n_estimation, noise)
        n_screen = (min(nominal.n_estimation, self.screen_samples or SCREEN_SAMPLES)
                    * (3 if recording.has_pressures else 1))
        basis = NominalBaseline(noise, cost0, n_res, nominal.fit_percent, floor, self.validation_fraction, nominal)
        return DiagnosisRun(recording, nominal.rig, basis, stages, max_refits=self.max_refits,
                            max_lookalikes=self.max_lookalikes, max_findings=self.max_findings,
                            several_effects=self.several_effects,
                            screen_samples=self.screen_samples, n_screen=n_screen,
                            say=lambda message: self._say(name, message))

    def _screen(self, run: DiagnosisRun, candidates: list, signatures: dict):
        """4. Screen the candidates by the route the nominal fit calls for (:func:`.rules.screening_route`);
        ``run.trials`` gets a trial per effect.  Returns ``(route, ranked, variants, measure)``, ``measure`` what
        the confirmation needs (the nominal cost on the screening window, or the nominal pre-fit's residual on
        the data sheet's window)."""
        basis = run.baseline
        room = validation_room(basis.fit0, basis.floor)
        rms_ratio = basis.rms(basis.cost0)
        route = screening_route(room, rms_ratio)
        if route == "none":
            run.say(f"the nominal validation error {100 - basis.fit0:.3g} points is within the keep test's reach of "
                    f"the noise floor F = {basis.floor:.3g}: nothing can be found, no candidate is screened")
            return route, [], {}, None
        if route == "from the data sheet":
            run.say(f"the nominal fit ends {rms_ratio:.3g} times above noise (more than {MODEL_SHORT:g}): every "
                    "candidate is screened from the data sheet")
            start = mismatch_window(basis.fit, run.recording, run.noise, WINDOW_SAMPLES)
            run.trials, variants, ranked, window = self.stages.screen_from_data_sheet(run, candidates, signatures,
                                                                                      start)
            run.say("screening from the data sheet ranks " + _ranking(ranked, variants))
            return route, ranked, variants, window.normalised_residual
        run.trials, variants, ranked, base_cost = self.stages.screen_around_nominal(run, candidates, signatures)
        run.say("screening ranks " + _ranking(ranked, variants))
        return route, ranked, variants, base_cost

    def _confirm(self, run: DiagnosisRun, route: str, ranked: list, variants: dict, measure) -> None:
        """5. Confirm the leading candidates by whole fits, as the screening's route calls for."""
        if route == "from the data sheet":
            self.stages.confirm_from_data_sheet(run, ranked, variants, measure)
        elif route == "around the nominal fit":
            self.stages.confirm_around_nominal(run, ranked, variants, measure)
