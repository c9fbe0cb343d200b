"""Far above noise, several effects found jointly: sets of effects pre-fitted together on the mismatch window.

Where no effect alone explains the window the screening from the data sheet looks at (:mod:`.from_data_sheet`),
the recording may lack several effects at once, and each effect alone is judged with the others missing: the
nominal parameters bend to make up for them, a true effect can even make the window worse alone (a leak to
atmosphere whose valve offset, holding the piston against it, is missing too), and the first finding is then a
look-alike or the wrong variant of the right physics.  Fitted one after the other, a wrong first finding is
inherited by every later step.  Here the effects are fitted together instead, first where it is cheap:

1. a transport delay, whose value has no gradient and was screened at a few values only, is first followed
   downhill on the window from its best screened value (:func:`refine_delay`): at a wrong value it loses the
   window to its look-alike, the spool lag, whose lag is a fitted parameter;
2. the window's leading effects (:data:`~.rules.SET_LEADERS`, each by its best pre-fit alone; not an effect whose
   ``window_pairs`` is False, heat transfer, whose free temperatures take up whatever else is missing) enter, each with
   every variant of its own physics (each leakage path: which path leaks is only seen with the others present;
   of a transport delay only its best value, a value and not a physics);
3. every pair of leaders, each variant of each, is pre-fitted together from the data sheet on the window
   (:func:`pneusim.fit.prefit_recording`, as the single effects were).

A third effect is not chosen on the window: where one leader explains little alone, a third one on the window is
as often a look-alike of the effect still missing (a load for seals that drag harder one way, heat transfer for
almost anything) as the effect itself; the search on top of the pair's whole fit, where the nominal parameters no
longer bend, screens every candidate of the vocabulary instead.

Every pre-fit is judged by its objective, the residuals plus the continuity defects it left open, weighted as it
weighed them (:attr:`pneusim.fit.PrefitResult.objective`): a pre-fit whose segments end apart bought part of its
residual with the jumps, and an effect with states of its own has more states to jump.  The set of the lowest
information criterion on the window, ``N ln C + k ln N`` (:func:`criterion`), singles included, is the joint
candidate (:func:`search_sets`).  Where it holds two effects or more and brings the window within
:data:`~.rules.SET_EXPLAINS_WINDOW` (a set that leaves more explains too little to choose the physics) and below
:data:`~.rules.SET_SHRINK` of the best single effect's objective, it is fitted whole from its pre-fit values and
kept by the keep test against the nominal model (:func:`fit_set`); the diagnosis then tests each member with the
others present (drop-one, :func:`.findings.drop_one`) and goes on on top of the survivors.  Where it is a single
effect, or its whole fit fails the test, the one-effect-first confirmation runs as before
(:func:`.from_data_sheet.confirm_from_data_sheet`).

A pre-fit of a window costs a few seconds; a whole fit from the data sheet costs one to five nominal fits.  The
window decides which set is fitted whole; the whole fit, the keep test and drop-one decide what is found.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass

from ..model import make_effect
from ..model.effects.transport_delay import DELAY_SCAN_S, SAMPLE_FRACTION
from .candidates import Candidate
from .delay import DELAY, on_grid, parabola_in_log
from .from_data_sheet import data_sheet_start
from .refits import effect_at_prefit, estimation_cost
from .result import CandidateTrial
from .rules import (MODEL_SHORT, PREFIT_START, RIVAL_WINDOW, SCAN_FACTOR, SET_LEADERS, WINDOW_DELAY_STEPS,
                    bic_penalty, is_solver_failure)

__all__ = ["WindowSet", "criterion", "leading_variants", "search_sets", "refine_delay", "fit_set", "fit_best_set",
           "subset_from_prefit"]


@dataclass
class WindowSet:
    """A set of candidates pre-fitted together on the mismatch window (``prefit`` None where it failed,
    ``error`` then says why)."""

    candidates: tuple
    prefit: object = None
    error: str = ""
    #: where the set was fitted whole: the keep test's outcome against the nominal model (or why the fit failed)
    outcome: str = ""

    @property
    def names(self) -> tuple:
        """The effects' vocabulary names."""
        return tuple(c.name for c in self.candidates)

    @property
    def label(self) -> str:
        """The variants, as the progress lines and the report name them."""
        return " + ".join(c.label for c in self.candidates)

    @property
    def n_added(self) -> int:
        """Parameters the set adds to the nominal model."""
        return sum(c.n_added for c in self.candidates)

    @property
    def normalised_objective(self) -> float:
        """The pre-fit's objective rms in noise units (infinity where it failed)."""
        return self.prefit.normalised_objective if self.prefit is not None else math.inf

    def to_dict(self) -> dict:
        return {"effects": list(self.names), "variants": self.label,
                "window_objective_normalised": (None if self.prefit is None
                                                else float(f"{self.normalised_objective:.6g}")),
                "criterion": None if self.prefit is None else float(f"{criterion(self):.6g}"),
                **({"error": self.error} if self.error else {}),
                **({"fitted_whole": self.outcome} if self.outcome else {})}


def criterion(window_set: WindowSet) -> float:
    """The set's information criterion on the window, ``N ln C + k ln N`` (``C`` its pre-fit objective, ``N`` the
    window's residuals, ``k`` the parameters it adds); infinity where its pre-fit failed.  Lower is better."""
    pre = window_set.prefit
    if pre is None or not math.isfinite(pre.objective) or pre.objective <= 0:
        return math.inf
    n = max(pre.n_residuals, 2)
    return n * math.log(pre.objective) + bic_penalty(window_set.n_added, n)


def leading_variants(singles: dict, leaders: int = SET_LEADERS) -> dict:
    """The window's leading effects and the variants of each that enter the sets: ``{effect: [candidate, ...]}``,
    at most ``leaders`` effects in order of their best pre-fit alone (``singles``: ``{label: (candidate, pre-fit
    or None)}``), each with its best variant first, then its best variant of each other physics (the
    candidates' ``option_values``: a leak's path), not its other values of the same physics (a delay's)."""
    best: dict = {}
    for c, pre in singles.values():
        if pre is None:
            continue
        options = tuple(sorted(c.effect.option_values.items()))
        per_effect = best.setdefault(c.name, {})
        if options not in per_effect or pre.objective < per_effect[options][1].objective:
            per_effect[options] = (c, pre)
    order = sorted(best, key=lambda name: min(p.objective for _, p in best[name].values()))
    return {name: [c for c, _ in sorted(best[name].values(), key=lambda cp: cp[1].objective)]
            for name in order[:max(0, leaders)]}


def _prefit_set(run, candidates, options: dict) -> WindowSet:
    """Pre-fit ``candidates`` together from the data sheet (each at its screening start, the nominal parameters
    at every candidate's ``start_scale``) on the window ``options`` describes."""
    start = {}
    for c in candidates:
        start.update(data_sheet_start(run.rig, c) or {})
    label = " + ".join(c.label for c in candidates)
    try:
        pre = run.stages.prefit(run.recording, run.rig, [c.effect for c in candidates], start_values=start or None,
                                **options)
    except Exception as exc:  # noqa: BLE001 - a set that cannot be integrated is reported, not raised
        if not is_solver_failure(exc):
            raise
        run.say(f"together on the window: {label} failed ({exc})")
        return WindowSet(tuple(candidates), None, str(exc))
    run.say(f"together on the window: {label} ends at {pre.normalised_objective:.3g} times noise")
    return WindowSet(tuple(candidates), pre)


def search_sets(run, singles: dict, options: dict, max_effects: int) -> list[WindowSet]:
    """Pre-fit pairs of the window's leading effects together (module docstring), each variant of each, after the
    best screened transport delay is followed downhill (:func:`refine_delay`; ``singles`` gains the delays it
    tried).  ``singles``: ``{label: (candidate, pre-fit or None)}``, the screening's pre-fits alone; ``options``:
    the window's pre-fit options; ``max_effects`` below 2 pre-fits no pair.  Returns every set tried and every
    single, best :func:`criterion` first."""
    refine_delay(run, singles, options)
    sets = [WindowSet((c,), pre) for c, pre in singles.values() if pre is not None]
    variants = leading_variants({k: (c, pre) for k, (c, pre) in singles.items() if c.effect.window_pairs})
    if max_effects < 2 or len(variants) < 2:
        return sorted(sets, key=criterion)
    for a, b in itertools.combinations(variants, 2):
        for ca, cb in itertools.product(variants[a], variants[b]):
            sets.append(_prefit_set(run, (ca, cb), options))
    return sorted(sets, key=criterion)


def refine_delay(run, singles: dict, options: dict) -> None:
    """Follow the best transport delay downhill on the window: the effect's own scan (``DELAY_SCAN_S``) beside the
    screened delays, then from the best of all pre-fits at delays a factor :data:`~.rules.SCAN_FACTOR` on either
    side, on along the side that lowers the objective, at most :data:`~.rules.WINDOW_DELAY_STEPS` of them, then at
    the vertex of a parabola in log(delay) through the best and its neighbours (each on the grid of
    :func:`.delay.on_grid`); each joins ``singles``.  Only where a screened delay lowers the window's objective
    below the nominal model's at all.

    Why: the screened delays sit around the lag of the nominal residual's cross-correlation with the command,
    which other missing physics moves (practice recordings screened at 19-51 ms for a 10.8 ms delay); a delay
    two samples off leaves most of the window unexplained and its look-alike, the spool lag, takes its place."""
    delays = [(pre.objective, c) for c, pre in singles.values() if pre is not None and c.name == DELAY]
    window = run.window
    if not delays or window is None:
        return
    if not min(o for o, _ in delays) < window.base.objective:
        return
    dt = run.recording.sample_time_s
    tried = {round(c.effect.values["delay_s"] / dt, 6): o for o, c in delays}

    def at(delay_s: float) -> float:
        delay_s = on_grid(delay_s, dt)
        key = round(delay_s / dt, 6)
        if key not in tried:
            c = Candidate(DELAY, f"transport delay {delay_s * 1e3:.3g} ms", make_effect(DELAY, delay_s=delay_s), [])
            pre = _prefit_set(run, (c,), options).prefit
            singles[c.label] = (c, pre)
            tried[key] = pre.objective if pre is not None else math.inf
        return tried[key]

    for d in DELAY_SCAN_S:       # the effect's own scan too: a lag moved far by other physics misses the valley
        if d >= SAMPLE_FRACTION * dt:
            at(d)
    best_objective, key = min((o, k) for k, o in tried.items())
    d0 = key * dt
    steps = WINDOW_DELAY_STEPS
    up, down = at(d0 * SCAN_FACTOR), at(d0 / SCAN_FACTOR)
    steps -= 2
    factor = SCAN_FACTOR if up < down else 1.0 / SCAN_FACTOR
    d, value = d0 * factor, min(up, down)
    while steps > 0 and value < best_objective:
        best_objective = value
        d *= factor
        value = at(d)
        steps -= 1
    # the vertex of a parabola in log(delay) through the best and its neighbours: the valley between grid points
    points = sorted((k * dt, objective) for k, objective in tried.items() if math.isfinite(objective))
    k = min(range(len(points)), key=lambda i: points[i][1])
    vertex = parabola_in_log([d for d, _ in points], [o for _, o in points], k)
    if vertex is not None:
        at(vertex)


def fit_best_set(run, sets: list, window_nominal: float):
    """The window's best set, ``sets[0]``, fitted whole (:func:`fit_set`); where that fit passes the keep test but
    ends more than :data:`~.rules.MODEL_SHORT` times above noise on the estimation part, the same effects through
    their other variants (a leak's other paths) that the window ranked within :data:`~.rules.RIVAL_WINDOW` times the
    best set's objective are fitted whole too, in the window's order, until one ends within that; the lowest on the
    estimation part is kept.  Returns ``(set, (fit, cost, kept))``, or ``(sets[0], None)`` where its fit failed.

    Why: far from noise, a pre-fit of the window ranks the paths of a leak by a fraction of its objective, and the
    whole part tells them apart where the window does not: a leak from chamber A with a valve offset ended 1.36 times
    above noise, fitted whole, where the path the window preferred, B, ended 7.19 times above it.  Fitted from the
    wrong path, drop-one then tested the offset against a fit still far above noise and dropped it
    (``docs/decisions/0140``)."""
    best = sets[0]
    out = fit_set(run, best, window_nominal)
    if out is None or not out[2]:
        return best, out
    for other in [w for w in sets[1:] if set(w.names) == set(best.names)
                  and w.normalised_objective <= RIVAL_WINDOW * best.normalised_objective]:
        rms = run.baseline.rms(out[1])
        if not rms > MODEL_SHORT:
            break
        run.say(f"{best.label} ends {rms:.3g} times noise on the estimation part (more than {MODEL_SHORT:g}): "
                f"{other.label} fitted whole too")
        again = fit_set(run, other, window_nominal,
                        ranked=f"another path of the set the window ranked best, {best.label}, which ended {rms:.3g} "
                               f"times above noise fitted whole; {other.label}")
        if again is not None and again[2] and again[1] < out[1]:
            best, out = other, again
    return best, out


def fit_set(run, best: WindowSet, window_nominal: float, ranked: str | None = None):
    """Fit the set ``best`` whole from the data sheet, each effect and the nominal parameters from its pre-fit
    (the nominal ones only where the pre-fit explained the window, :data:`~.rules.PREFIT_START` of the nominal
    pre-fit's ``window_nominal``), and apply the keep test against the nominal model.  Each member's trial records
    the outcome (``ranked``: how the set was chosen, where it was not the window's best).  Returns ``(fit, cost,
    kept)``, or None where the fit failed."""
    ranked = ranked or f"the set that explains the mismatch window best, {best.label}"
    run.say(f"fit with {best.label} together from the data sheet")
    started = time.perf_counter()
    try:
        fit = _from_prefit(run, best, window_nominal)
    except Exception as exc:  # noqa: BLE001 - a failed fit is reported in the trials
        if not is_solver_failure(exc):
            raise
        best.outcome = f"failed: {exc}"
        for c in best.candidates:
            _trial_note(run, c, f"fitted together with {_others(best, c)} from the data sheet: failed: {exc}")
        return None
    seconds = time.perf_counter() - started
    basis = run.baseline
    cost, _ = estimation_cost(fit, run.noise)
    kept, _, reason = run.stages.keep_test(basis.cost0, cost, basis.n_residuals, best.n_added, basis.fit0,
                                           fit.fit_percent, basis.floor)
    best.outcome = f"validation {fit.fit_percent:.2f} %: {reason}" + ("" if kept else " (not kept)")
    for c in best.candidates:
        trial = _trial_note(run, c, f"fitted together with {_others(best, c)} from the data sheet ({ranked}, "
                                    f"{best.normalised_objective:.3g} times the noise there): {reason}")
        trial.seconds = (trial.seconds or 0.0) + seconds / len(best.candidates)
        trial.refitted = True
        trial.fit_percent, trial.improvement_points = fit.fit_percent, fit.fit_percent - basis.fit0
    return fit, cost, kept


def _from_prefit(run, window_set: WindowSet, window_nominal: float):
    """The whole fit of ``window_set`` from the data sheet, each effect and the nominal parameters from its pre-fit
    on the window (the nominal ones only where the pre-fit explained the window, :data:`~.rules.PREFIT_START` of
    the nominal pre-fit's ``window_nominal``)."""
    pre = window_set.prefit
    effects = [effect_at_prefit(c, pre) for c in window_set.candidates]
    explained = pre.normalised_objective <= PREFIT_START * window_nominal
    nominal_start = {k: v for k, v in pre.estimates.items() if "." not in k} if explained else None
    return run.stages.fit(run.recording, run.rig, effects, run.baseline.validation_fraction, nominal_start)


def subset_from_prefit(run, names) -> tuple:
    """The set fitted whole (``run.joint``) without some of its members, fitted as the set was: from the data
    sheet at the subset's own pre-fit on the window.  ``names``: the effects left.  Returns ``(fit, note)``:
    ``fit`` None where ``names`` is not a subset of the joint set, where the subset has no pre-fit on the window,
    where that pre-fit ends more than :data:`~.rules.RIVAL_WINDOW` times above the set's (no rival for it, as a
    candidate that far behind the first finding is not fitted whole), or where its fit fails; ``note`` says why
    (empty when no joint set was fitted).

    Why: drop-one's fit without a member is warm from the set's optimum, where the nominal parameters have moved
    to work with that member; the set itself was fitted from the data sheet.  The subset deserves the same start:
    a member is only needed where the best fit found without it is worse (a dead band alone, fitted from the
    data sheet, validated above the dead band and a leak that drop-one had kept against its warm refit)."""
    joint = run.joint
    if joint is None:
        return None, ""
    names = set(names)
    if not names or not names < set(joint.names):
        return None, ""
    labels = sorted(c.label for c in joint.candidates if c.name in names)
    subset = next((w for w in run.window_sets if sorted(c.label for c in w.candidates) == labels
                   and w.prefit is not None), None)
    if subset is None:
        return None, "no pre-fit on the window without it"
    ratio = subset.normalised_objective / joint.normalised_objective
    if ratio > RIVAL_WINDOW:
        return None, (f"without it the window's pre-fit ends {ratio:.3g} times the set's, above {RIVAL_WINDOW:g}: "
                      "not fitted from the data sheet")
    run.say(f"drop-one: {subset.label} from the data sheet, as the set was fitted")
    try:
        return _from_prefit(run, subset, run.window.base.normalised_objective), ""
    except Exception as exc:  # noqa: BLE001 - the warm refit stands
        if not is_solver_failure(exc):
            raise
        return None, f"its fit from the data sheet failed ({exc})"


def _others(window_set: WindowSet, c) -> str:
    return ", ".join(x.label for x in window_set.candidates if x is not c) or "nothing"


def _trial_note(run, c, text: str):
    """``c``'s trial (added where the screening made none) with ``text`` appended to its status."""
    trial = run.trials.get(c.name)
    if trial is None:
        trial = run.trials[c.name] = CandidateTrial(c.name, math.nan, "screened together with others on the window",
                                                    status="")
    trial.status = text if trial.status in ("", "not refitted") else f"{trial.status}; {text}"
    return trial
