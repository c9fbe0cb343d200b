"""The findings of a diagnosis: the kept candidate with the best validation fit first, then more effects on
top of it, one at a time (:func:`add_findings`), each with its parameters as a user compares them with a data
sheet; then each finding tested with the others present (:func:`drop_one`).  What the findings leave
unexplained is :mod:`.other`'s.
"""

from __future__ import annotations

import math
import time

from ..model.effects import EFFECTS
from .candidates import family_of
from .from_data_sheet import data_sheet_start
from .other import above_noise, unexplained
from .refits import effect_at_screened, effect_parameters, estimation_cost, rescued
from .result import CandidateTrial, Finding
from .rules import MIN_EXPLAINED, MODEL_SHORT, ON_TOP_REFITS, RIVAL_ON_TOP, bic_penalty, is_solver_failure
from .window_sets import subset_from_prefit

__all__ = ["add_findings", "more_findings", "drop_one", "joint_finding", "rank_by_contribution", "refreshed",
           "ON_TOP_REFITS"]


def add_findings(run, kept: list) -> tuple[list, object]:
    """The first finding (the kept candidate with the best validation fit, ``kept[0]``) and more effects on top
    of it, one at a time; returns ``(findings, final fit)``.

    Every candidate not yet a finding (the other kept ones, those of ``run.second_only`` and of
    ``run.on_top``: the vocabulary's variants the first round did not fit) is screened on top of the findings'
    fit; the one that explains most of the residual there is refitted together with them while it explains at
    least :data:`~.rules.MIN_EXPLAINED` of it (at most :data:`~.rules.ON_TOP_REFITS` refits on top of each set
    of findings), and kept when it passes the keep test against the findings before it (and against those
    refitted alone: :func:`_second_effect_needed`).  Once one is kept, the rest are screened again on top of the
    new findings, up to ``run.max_findings``.  ``run.trials`` are updated in place (a trial is added for a
    candidate the first round did not screen).

    Why by the screening on top, not by the fit alone: once the first finding is in, what a further effect
    must explain is the findings' residual, and a candidate that fitted well alone often explained the same as
    the first, while a true second effect that fitted badly alone, or was never fitted, would not be tried
    (``docs/decisions/0032``)."""
    first = kept[0]
    final = rescued(run, run.refits[first][0], lambda fit: above_noise(fit, run.noise, run.baseline.floor),
                    "first finding")
    run.refits[first] = (final, run.refits[first][1])
    findings = [_finding(first, final, run.baseline.fit0, run.trials[first])]
    pool = {eff: run.refits[eff][1] for eff in kept[1:]}
    pool.update(run.second_only)
    if run.several_effects:
        pool.update(_wide_pool(run, findings, pool))
    return _search_on_top(run, findings, final, pool)


def more_findings(run, findings: list, final) -> tuple[list, object]:
    """The several-effects search continued on top of the one-effect-first search's ``findings`` (their fit
    ``final``): every candidate of ``run.on_top`` not yet a finding and not yet refitted on top, screened on top
    of ``final`` and refitted as in :func:`add_findings`, up to ``run.max_findings``.  Returns ``(findings,
    final)``.

    Why: where the one-effect-first search leaves the model above noise, the effect still missing is often
    one the first round never confirmed (it fitted badly alone while the first was missing); candidates already
    refitted on top of the same findings would fail the same test again."""
    return _search_on_top(run, findings, final, _wide_pool(run, findings, {}))


def _wide_pool(run, findings: list, pool: dict) -> dict:
    """Every candidate of ``run.on_top`` (the vocabulary's variants) that is not a finding, not in ``pool`` and
    not refitted on top before, by label.  A finding's look-alikes stay in: a load and seals that drag harder one
    way are one family and often come together (``docs/decisions/0107``)."""
    found = {f.effect for f in findings}
    return {label: c for label, c in run.on_top.items()
            if c.name not in found and c.name not in pool and label not in pool and label not in run.refitted_on_top}


def _search_on_top(run, findings: list, final, pool: dict) -> tuple[list, object]:
    """One more finding at a time from ``pool`` (:func:`_one_more`) up to ``run.max_findings``."""
    while pool and len(findings) < run.max_findings:
        added, final = _one_more(run, findings, final, pool)
        if not added:
            break
    return findings, final


def _trial_of(run, c):
    """The candidate's trial, added for one the first round did not screen."""
    if c.name not in run.trials:
        run.trials[c.name] = CandidateTrial(c.name, math.nan, "not screened alone: screened on top of the findings")
    return run.trials[c.name]


def _one_more(run, findings: list, final, pool: dict) -> tuple[bool, object]:
    """Screen ``pool`` on top of ``final`` and refit the candidates that explain most there, at most
    :data:`~.rules.ON_TOP_REFITS`, or every one that explains at least :data:`~.rules.MIN_EXPLAINED` there while
    ``final`` leaves physics unexplained (:func:`.other.unexplained`); the first that passes becomes a finding.
    Returns ``(added, final)``; ``pool`` loses the candidates refitted and, once one is kept, every variant of
    its effect.

    Why more while unexplained: the search ending here is what lets a diagnosis say ``other``, "no vocabulary
    effect passes the test on top of the findings", and that is only true of the candidates tested; the cap
    saves time where the findings are near noise and a further effect would be a detail, not where the model
    is still far off (``docs/decisions/0127``)."""
    names = ", ".join(f.effect for f in findings)
    base_top, scores = _screen_on_top(run, final, pool)
    refitted = 0
    while pool and (refitted < ON_TOP_REFITS or unexplained(final, run.noise, run.baseline.floor)[0]):
        key = max(pool, key=lambda k: scores[k][1])
        gain, score_top, _ = scores[key]
        if math.isfinite(gain) and not score_top > MIN_EXPLAINED * base_top:
            break
        share = gain / base_top if math.isfinite(gain) and base_top > 0 else math.nan   # nan: nothing to compare
        refitted += 1
        c = pool.pop(key)
        run.refitted_on_top.update({key, c.label})    # the first round's pools key by effect, run.on_top by label
        screened = f" (screening explains {gain:.0f} of {base_top:.0f} there)" if math.isfinite(gain) else ""
        tried = _refit_on_top(run, names, final, c, screened, scores[key][2] if run.several_effects else None)
        if tried is None:
            continue
        ok, fit2, c_prev, c2 = tried
        if ok:
            previous = final
            ok, final = _second_effect_needed(run, final, c_prev, fit2, c2, c.name, c.n_added, findings)
            if final is not previous:
                base_top, scores = _screen_on_top(run, final, pool)   # the rest, on top of the better optimum
        if ok:
            fit2, c2 = _grown_from_data_sheet(run, final, c, fit2, c2)
            c, fit2 = _rival_look_alike(run, names, final, pool, scores, base_top, c, fit2, c2, share)
            run.trials[c.name].kept = True
            findings.append(_finding(c.name, fit2, final.fit_percent, run.trials[c.name]))
            for other_key in [k for k, v in pool.items() if v.name == c.name]:
                pool.pop(other_key)
            return True, fit2
    found = {f.effect for f in findings}
    for key, c in pool.items():
        trial = _trial_of(run, c)
        if c.name not in found:
            trial.kept = False
            gain = scores.get(key, (math.nan,))[0]
            if not (math.isfinite(gain) and math.isfinite(base_top)):
                trial.status += f"; not screened on top of {names} (the screening failed or was not started)"
                continue
            trial.status += (f"; not refitted on top of {names}: its screening explains {gain:.0f} of "
                             f"{base_top:.0f} there (at most {ON_TOP_REFITS} are refitted on top, those that "
                             f"explain most and at least {MIN_EXPLAINED:g} of it; more only while the findings "
                             "leave physics unexplained)")
    return False, final


def _rival_look_alike(run, names: str, final, pool: dict, scores: dict, base_top: float, c, fit2, cost2: float,
                      share: float = math.nan):
    """``(candidate, fit)`` of the effect kept on top: ``c`` (refitted as ``fit2``, estimation cost ``cost2``), or its
    best-screened look-alike left in ``pool`` where that one, refitted on top of the same findings, passes the keep
    test too and ends lower on the estimation part.  The look-alike leaves ``pool``.  A look-alike whose screening
    on top explains less than :data:`~.rules.RIVAL_ON_TOP` times ``c``'s ``share`` (the fraction of the findings'
    cost on the screening window that ``c``'s screening explained) is no rival and is not refitted.

    Why: the screening on top ranks look-alikes by a few steps each (a load before seals that drag harder one
    way, where the seals are what is missing), and the first to pass the test would take the place of the other;
    between two look-alikes that both pass, what the whole estimation part says decides.  Why not every one: a
    look-alike costs one or two whole fits, and where its screening explains a fraction of the kept one's, its
    refit spends the budget the search on top and drop-one need (``docs/decisions/0131``)."""
    def is_rival(k) -> bool:
        gain, score, _ = scores[k]
        if not math.isfinite(gain):
            return True          # not screened: its refit decides
        return score > MIN_EXPLAINED * base_top and not gain < RIVAL_ON_TOP * share * base_top   # nan share: no bar

    family = [k for k, v in pool.items() if v.name in family_of(c.name) and v.name != c.name and is_rival(k)]
    if not family:
        return c, fit2
    key = max(family, key=lambda k: scores[k][1])
    rival = pool.pop(key)
    run.refitted_on_top.update({key, rival.label})
    gain = scores[key][0]
    screened = (f" (screening explains {gain:.0f} of {base_top:.0f} there; a look-alike of {c.name}, kept on top "
                "first)" if math.isfinite(gain) else f" (a look-alike of {c.name}, kept on top first)")
    tried = _refit_on_top(run, names, final, rival, screened, scores[key][2] if run.several_effects else None)
    if tried is None or not tried[0] or not tried[3] < cost2:
        run.trials[rival.name].status += f"; {c.name}, its look-alike, stays"
        return c, fit2
    run.trials[c.name].kept = False
    run.trials[c.name].status += (f"; replaced by {rival.name}, its look-alike, which passes the test on top of "
                                  f"{names} too and ends lower on the estimation part ({tried[3]:.0f} < {cost2:.0f})")
    return rival, tried[1]


def _screen_on_top(run, final, pool: dict) -> tuple[float, dict]:
    """What each candidate of ``pool`` still explains once the findings (``final``) are in: ``(base_top,
    {key: (gain, score, screening)})``, ``base_top`` the findings' own cost on the screening window.

    A refit on top costs as much as the first; look-alikes of the first usually explain nothing more.  From
    the findings' own cost, not from where the same steps take it without a candidate (as around the nominal
    optimum): a first finding far from noise gains much from those steps alone, and in a few steps a true
    second effect may not get past them.  Each from the effect's neutral start, as in the first screening:
    the trust region then only goes downhill from the findings' optimum.  Where the findings cannot be
    screened, the refits decide in the order given; a candidate that cannot be screened gets an infinite gain
    (its refit decides)."""
    try:
        base_top = run.stages.screen(final, run.recording, None, run.noise, run.screen_samples)["cost"]
    except Exception as exc:  # noqa: BLE001
        if not is_solver_failure(exc):
            raise
        base_top = math.nan
    scores = {}
    for key, c in pool.items():
        gain, screened = math.inf, None
        if math.isfinite(base_top):
            try:
                screened = run.stages.screen(final, run.recording, c, run.noise, run.screen_samples)
                gain = base_top - screened["cost"]
            except Exception as exc:  # noqa: BLE001
                if not is_solver_failure(exc):
                    raise
        scores[key] = (gain, gain - bic_penalty(c.n_added, max(run.n_screen, 2)), screened)
    return base_top, scores


def _refit_on_top(run, first: str, final, c, screened: str, screening: dict | None = None):
    """Refit the findings so far (``final``, named ``first``) with candidate ``c`` on top, warm from them (the
    candidate at its values screened on top, ``screening``, or else those of its first screening), and apply
    the keep test against them; where that fails and the findings' fit ends more than
    :data:`~.rules.MODEL_SHORT` times above noise, all fitted from the data sheet are tested instead.  Returns
    ``(kept, fit, cost before, cost after)``, or None when the refit failed (the trial says why)."""
    eff = c.name
    trial, basis = _trial_of(run, c), run.baseline
    effect = effect_at_screened(c, screening if screening and screening.get("parameters") else
                                {"parameters": trial.parameters})
    from_sheet = effect if screening else None   # the one-effect-first search refits from the data sheet as before
    run.say(f"refit with {first} and {c.label}")
    trial.kept, trial.refitted = False, True
    started = time.perf_counter()
    try:
        fit2 = run.stages.refit(run.recording, run.rig, list(final.effects_) + [effect], final)
    except Exception as exc:  # noqa: BLE001
        if not is_solver_failure(exc):
            raise
        trial.status += f"; with {first}: refit failed: {exc}"
        return None
    finally:
        trial.seconds = (trial.seconds or 0.0) + time.perf_counter() - started
    c_prev, _ = estimation_cost(final, run.noise)
    c2, _ = estimation_cost(fit2, run.noise)
    ok, _, reason = run.stages.keep_test(c_prev, c2, basis.n_residuals, c.n_added, final.fit_percent,
                                         fit2.fit_percent, basis.floor)
    trial.status += f"; on top of {first}{screened}: {reason}"
    if not ok and basis.rms(c_prev) > MODEL_SHORT:
        both = _on_top_from_data_sheet(run, final, c, trial, from_sheet)
        if both is not None:
            fit2, c2 = both
            ok, _, reason = run.stages.keep_test(c_prev, c2, basis.n_residuals, c.n_added, final.fit_percent,
                                                 fit2.fit_percent, basis.floor)
            trial.status += f"; both fitted from the data sheet: {reason}"
    return ok, fit2, c_prev, c2


def _on_top_from_data_sheet(run, final, c, trial, effect=None):
    """Fit the findings so far (``final``'s effects, at their fitted values) and candidate ``c`` (at its own
    start) together from the data sheet (``run.stages.fit``); returns ``(fit, estimation cost)``, or None when
    the fit fails.

    Why: used where the findings' fit still ends more than :data:`~.rules.MODEL_SHORT` times above the noise
    and the refit on top of it failed the test.  Its nominal parameters have then bent to make up for the
    physics still missing, as the nominal fit's had (see :mod:`.from_data_sheet`), and a refit warm from them
    stays in their basin, its result decided by its start (``docs/decisions/0032``)."""
    run.say(f"refit with {', '.join(e.name for e in final.effects_)} and {c.name} from the data sheet")
    started = time.perf_counter()
    try:
        fit2 = run.stages.fit(run.recording, run.rig, list(final.effects_) + [effect or c.effect],
                              run.baseline.validation_fraction, data_sheet_start(run.rig, c))
    except Exception as exc:  # noqa: BLE001 - a failed fit is reported in the result
        if not is_solver_failure(exc):
            raise
        trial.status += f"; both fitted from the data sheet: failed: {exc}"
        return None
    finally:
        trial.seconds = (trial.seconds or 0.0) + time.perf_counter() - started
    return fit2, estimation_cost(fit2, run.noise)[0]


def _grown_from_data_sheet(run, before, c, fit2, cost2: float):
    """``(fit, estimation cost)`` of the findings grown by ``c``: its refit warm from ``before`` (the findings' fit
    it grew from; ``fit2``, cost ``cost2``), or the same set fitted together from the data sheet where that ends
    lower on the estimation part.  Tried only where ``before`` ended more than :data:`~.rules.MODEL_SHORT` times
    above the noise and ``fit2`` still leaves physics unexplained (:func:`.other.unexplained`); the names do not
    change, only the fit they are judged by from here on (a look-alike of ``c``, the search on top, drop-one,
    ``other``).

    Why: ``before``'s nominal parameters had bent to make up for the effect still missing, and the grown set,
    warm from them, can stay in their basin; from the data sheet the same set can reach the noise where the warm
    chain ends far above it (``docs/decisions/0130``)."""
    if not fit2.solver.get("warm_start"):
        return fit2, cost2      # already fitted from the data sheet (the warm refit had failed the test)
    if not (run.baseline.rms(estimation_cost(before, run.noise)[0]) > MODEL_SHORT
            and unexplained(fit2, run.noise, run.baseline.floor)[0]):
        return fit2, cost2
    trial = run.trials[c.name]
    sheet = _on_top_from_data_sheet(run, before, c, trial)
    if sheet is None:
        return fit2, cost2
    from_sheet, cost_sheet = sheet
    if cost_sheet < cost2:
        trial.status += (f"; the grown set fitted from the data sheet ends lower on the estimation part "
                         f"({cost_sheet:.0f} < {cost2:.0f}; validation {fit2.fit_percent:.2f} -> "
                         f"{from_sheet.fit_percent:.2f} %): the findings' fit from here on")
        return from_sheet, cost_sheet
    trial.status += (f"; the grown set fitted from the data sheet ends higher on the estimation part "
                     f"({cost_sheet:.0f} >= {cost2:.0f}; validation {from_sheet.fit_percent:.2f} %): the warm "
                     "refit stays")
    return fit2, cost2


def _second_effect_needed(run, final, cost_final: float, fit2, cost2: float, eff: str, n_added: int,
                          findings: list) -> tuple:
    """Whether ``eff``, kept on top of the findings so far (``final``, estimation cost ``cost_final``;
    refitted with ``eff`` as ``fit2``, cost ``cost2``), is needed, or whether the refit on top only found a
    better optimum of the findings so far: those alone are refitted warm from ``fit2``, and where that
    refit ends below ``final`` on the estimation part, ``eff`` must pass the keep test against it too.
    Returns ``(needed, final)``, ``final`` replaced by that refit when ``eff`` is not needed (the last
    finding then rebuilt on it).

    Why: a refit on top runs the optimiser on from the first finding's optimum with one more parameter, and
    where that first fit had stopped short, the gain is the optimiser's.  Where the refit alone ends above
    ``final`` on the estimation part (what the fit minimises), ``final`` had not stopped short, and the test
    ``eff`` passed against it stands: tested against that refit instead, a true second effect can fall just
    short of the threshold (``docs/decisions/0032``)."""
    trials, noise, basis = run.trials, run.noise, run.baseline
    run.say(f"{eff} kept on top: the findings before it refitted alone from there")
    try:
        alone = run.stages.refit(run.recording, run.rig, list(final.effects_), fit2)
        cost_alone, _ = estimation_cost(alone, noise)
    except Exception as exc:  # noqa: BLE001 - the refit on top stands
        if not is_solver_failure(exc):
            raise
        return True, final
    if not cost_alone < cost_final:
        trials[eff].status += (f"; the findings before it refitted alone from that optimum end above their own fit "
                               f"on the estimation part ({cost_alone:.0f} >= {cost_final:.0f}; validation "
                               f"{alone.fit_percent:.2f} %): they had not stopped short, the test above stands")
        return True, final
    needed, _, reason = run.stages.keep_test(cost_alone, cost2, basis.n_residuals, n_added, alone.fit_percent,
                                             fit2.fit_percent, basis.floor)
    trials[eff].status += (f"; against the findings before it refitted alone from that optimum "
                           f"({alone.fit_percent:.2f} %): {reason}")
    if needed:
        return True, final
    last = findings[-1]
    trials[last.effect].status += (f"; refitted from the optimum found with {eff} on top: validation "
                                   f"{final.fit_percent:.2f} -> {alone.fit_percent:.2f} %")
    findings[-1] = _finding(last.effect, alone, last.fit_percent - last.improvement_points, trials[last.effect])
    return False, alone


def _finding(eff: str, fit, fit_before: float, trial: CandidateTrial) -> Finding:
    values, errors = effect_parameters(fit, eff)
    return Finding(effect=eff, evidence=trial.evidence + f"; refit: {trial.status}",
                   parameters=_derived(eff, values, fit), fit_percent=fit.fit_percent,
                   improvement_points=fit.fit_percent - fit_before, standard_errors=errors)


def joint_finding(eff: str, fit, fit_before: float, trial: CandidateTrial) -> Finding:
    """A finding of a set found jointly (:mod:`.window_sets`): its parameters as fitted together with the others,
    the set's validation fit, its improvement over ``fit_before`` (:func:`rank_by_contribution` then says what
    each adds with the others present)."""
    return _finding(eff, fit, fit_before, trial)


def rank_by_contribution(run, findings: list, final) -> list:
    """Findings found together, most important first: by what each adds to the validation fit with all the others
    present (``run.contributions``, drop-one's last test; one never tested keeps its place after the tested ones).
    Each finding's ``fit_percent`` is then the final fit and its ``improvement_points`` that contribution (with
    one finding left, its improvement over the nominal model).

    Why not the order they were found in: found together, no finding came first; what each explains that the
    others cannot is its importance (``diagnosis.md``: most important first)."""
    if len(findings) < 2:
        for f in findings:
            f.fit_percent, f.improvement_points = final.fit_percent, final.fit_percent - run.baseline.fit0
        return findings
    tested = [f for f in findings if f.effect in run.contributions]
    ranked = sorted(tested, key=lambda f: -run.contributions[f.effect]) + [f for f in findings if f not in tested]
    for f in ranked:
        f.fit_percent = final.fit_percent
        f.improvement_points = run.contributions.get(f.effect, f.improvement_points)
    return ranked


def _derived(name: str, values: dict, fit) -> dict:
    """Parameters a user compares with a data sheet, derived from the fitted ones (the effect's own
    :meth:`~pneusim.model.effects.Effect.derived_parameters`)."""
    cls = EFFECTS.get(name)
    if cls is None:
        return dict(values)
    est = fit.estimates
    return cls.derived_parameters(values, lambda key: est.get(key, fit.rig_.params[key]))


def drop_one(run, findings: list, final) -> tuple[list, object]:
    """Each finding tested with the others present: the findings' fit without it (refitted warm from ``final``)
    against the fit with all, by the keep test; a finding that fails is dropped (the one that adds least
    first, then the rest tested again) and the fit without it becomes the final fit.  Returns ``(findings,
    final)``, each finding's parameters those of the final fit, where all are fitted together; ``run.contributions``
    holds what each adds to the validation fit with the others present (its last test).

    Why: a finding kept on top of the first may only have helped because another effect was still missing, and
    an early finding may be a look-alike the later ones make redundant; only the test with every other finding
    present tells (``diagnosis.md``: a finding that only helps because another one is missing is dropped).
    With one finding the keep test against the nominal model was that test.  Where the others are part of a set
    fitted jointly from the data sheet, a finding that passes against the warm fit without it is also tested
    against the others fitted as the set was (:func:`_against_subset_from_prefit`): the warm fit starts where the
    nominal parameters moved to work with the finding, and a look-alike can pass against it alone."""
    basis = run.baseline
    while len(findings) >= 2:
        c_final, _ = estimation_cost(final, run.noise)
        tests = []
        for f in findings:
            others = [e for e in final.effects_ if e.name != f.effect]
            run.say(f"drop-one: the findings without {f.effect}")
            started = time.perf_counter()
            try:
                without = run.stages.refit(run.recording, run.rig, others, final)
            except Exception as exc:  # noqa: BLE001 - an untested finding stays
                if not is_solver_failure(exc):
                    raise
                run.trials[f.effect].status += f"; drop-one: the fit without it failed ({exc}): kept"
                continue
            finally:
                run.trials[f.effect].seconds = (run.trials[f.effect].seconds or 0.0) + time.perf_counter() - started
            c_without, _ = estimation_cost(without, run.noise)
            k = _added_parameters(final, f.effect)

            def judge(fit, cost):
                """The keep test of ``f`` against ``fit`` without it (estimation cost ``cost``): ``(ok, reason)``."""
                ok, _, reason = run.stages.keep_test(cost, c_final, basis.n_residuals, k, fit.fit_percent,
                                                     final.fit_percent, basis.floor)
                return ok, reason

            ok, reason = judge(without, c_without)
            if ok:
                without, ok, reason = _against_subset_from_prefit(run, f, others, without, c_without, reason, judge)
            run.trials[f.effect].status += (f"; drop-one, with {', '.join(e.name for e in others) or 'nothing'} "
                                            f"present (validation {without.fit_percent:.2f} % without it): {reason}")
            run.contributions[f.effect] = final.fit_percent - without.fit_percent
            tests.append((ok, final.fit_percent - without.fit_percent, f, without))
        dropped = sorted((t for t in tests if not t[0]), key=lambda t: t[1])
        if not dropped:
            break
        _, _, f, without = dropped[0]
        run.trials[f.effect].kept = False
        run.trials[f.effect].status += "; dropped: it only helped while another effect was missing"
        findings = [g for g in findings if g is not f]
        final = without
    return [_refreshed(f, final) for f in findings], final


def _against_subset_from_prefit(run, f, others: list, without, c_without: float, reason: str, judge) -> tuple:
    """Where ``f`` passed drop-one (``reason``) against the warm fit ``without`` it (estimation cost ``c_without``),
    and the findings left without it, ``others``, are part of the set fitted jointly: they are fitted as the set
    was, from the data sheet at their own window pre-fit (:func:`.window_sets.subset_from_prefit`); where that ends
    lower on the estimation part, it is the fit without ``f`` and ``judge(fit, cost) -> (ok, reason)``, the keep
    test, is applied again.  Returns ``(without, ok, reason)``."""
    started = time.perf_counter()
    cold, note = subset_from_prefit(run, [e.name for e in others])
    run.trials[f.effect].seconds = (run.trials[f.effect].seconds or 0.0) + time.perf_counter() - started
    if cold is None:
        return without, True, reason + (f" ({note})" if note else "")
    c_cold, _ = estimation_cost(cold, run.noise)
    if not c_cold < c_without:
        return without, True, reason + (f"; without it from the data sheet as the set was fitted "
                                        f"(validation {cold.fit_percent:.2f} %) ends higher on the "
                                        f"estimation part ({c_cold:.0f} >= {c_without:.0f})")
    ok, again = judge(cold, c_cold)
    return cold, ok, (reason + f"; without it from the data sheet as the set was fitted, lower on the estimation "
                               f"part ({c_cold:.0f} < {c_without:.0f}; validation {cold.fit_percent:.2f} %): {again}")


def _added_parameters(fit, name: str) -> int:
    """Parameters effect ``name`` adds in ``fit`` (for the information criterion)."""
    for e in fit.effects_:
        if e.name == name:
            free = [q for q in fit.parameters if q.startswith(f"{name}.")]
            return type(e).added_parameters(free)
    return 1


def refreshed(findings: list, final) -> list:
    """``findings`` with their parameters (and errors) as fitted in ``final``, where all are fitted together."""
    return [_refreshed(f, final) for f in findings]


def _refreshed(f: Finding, final) -> Finding:
    """``f`` with its parameters (and errors) as fitted in ``final`` together with the other findings."""
    if f.effect not in {e.name for e in final.effects_}:
        return f
    values, errors = effect_parameters(final, f.effect)
    f.parameters, f.standard_errors = _derived(f.effect, values, final), errors
    return f
