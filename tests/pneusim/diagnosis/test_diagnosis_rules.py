"""The rules that choose which candidates the diagnosis fits, and how, checked with stand-in fits.

Whole fits cost seconds to minutes each, so these tests pass stand-ins with set outcomes as the diagnosis's
stages (:class:`pneusim.diagnosis.DiagnosisStages`: ``fit``, ``refit``, ``screen``, ``keep_test``) and check
the decisions: which candidates far above noise are fitted whole and in which order
(:func:`pneusim.diagnosis.from_data_sheet.confirm_from_data_sheet`), where a whole fit starts, and how second
effects are tried on top of the first finding (:func:`pneusim.diagnosis.findings.add_findings`).  The
end-to-end diagnosis of simulated recordings is in ``test_diagnosis.py``.
"""

import math

import pytest
from stand_ins import NOISE, StandInFit, stand_in_run

from pneusim.diagnosis.candidates import Candidate
from pneusim.diagnosis.result import CandidateTrial
from pneusim.diagnosis.run import NominalBaseline
from pneusim.model import make_effect


def _confirm_with_stand_in_fits(ranked: list, outcome: dict, retried: dict | None = None, window: dict | None = None,
                                second_only: dict | None = None, window_nominal_rms: float = math.inf,
                                starts: dict | None = None) -> list:
    """Run :func:`confirm_from_data_sheet` on ``ranked`` effects (all screened with a positive score) with
    stand-in whole fits: ``outcome[effect] = (estimation rms in noise units, validation fit %)``, and
    ``retried[effect]`` the same for a refit warm from the nominal fit; the keep test keeps a fit that
    beats the nominal one's (rms 30, fit 0 %); ``window[effect]``: its pre-fit's rms on the window (noise
    units; unknown when not given).  Returns the effects fitted, in order (a warm refit as
    ``"EFFECT from the nominal fit"``), and the trials; ``second_only`` gets those left to the screening
    on top, and ``starts[effect]`` the nominal start values its whole fit was given."""
    from types import SimpleNamespace

    from pneusim.diagnosis.from_data_sheet import confirm_from_data_sheet

    n = 1000
    fitted = []

    def stand_in_fit(recording, rig, effects, validation_fraction, start_values=None):
        fitted.append(effects[0].name)
        (starts if starts is not None else {})[effects[0].name] = start_values
        return StandInFit(*outcome[effects[0].name], n=n)

    def stand_in_refit(recording, rig, effects, warm, start_values=None):
        fitted.append(effects[0].name + " from the nominal fit")
        return StandInFit(*retried[effects[0].name], n=n)

    variants, trials = {}, {}
    for i, name in enumerate(ranked):
        c = Candidate(name, name, make_effect(name), [])
        variants[name] = (1000.0 - i, c, SimpleNamespace(estimates={"moving_mass_kg": 1.65},
                                                         normalised_residual=(window or {}).get(name, math.nan)))
        trials[name] = CandidateTrial(name, 1000.0 - i, "", status="not refitted")
    nominal = StandInFit(30.0, 0.0, n=n)
    basis = NominalBaseline(NOISE, 30.0 ** 2 * n, n, 0.0, 0.2, 0.3, nominal)
    run = stand_in_run(basis, trials=trials, second_only=second_only, fit=stand_in_fit, refit=stand_in_refit,
                       keep_test=lambda c0, c1, n_, k, f0, f1, floor: (c1 < c0 and f1 > f0 + 1, 0.5, ""))
    run.max_refits, run.max_lookalikes = 3, 2
    confirm_from_data_sheet(run, ranked, variants, window_nominal_rms=window_nominal_rms)
    return fitted, trials


def test_confirm_from_data_sheet_fits_effects_without_states_first():
    """Far above noise, the leading families are fitted whole, those without states of their own first:
    the stop once a kept fit explains the recording to noise then spares the costly fits of the spool lag
    and heat transfer that a window ranked above the true load (practice2_15); the load's look-alikes are
    still fitted, the screened order kept within each kind."""
    fitted, _ = _confirm_with_stand_in_fits(
        ["heat_transfer", "valve_dynamics", "external_load", "friction_asymmetry",
                      "pressure_dependent_friction"],
        {"external_load": (1.0, 99.8), "friction_asymmetry": (15.0, 6.8), "pressure_dependent_friction": (20.0, 3.0),
         "heat_transfer": (19.0, -126.0), "valve_dynamics": (8.5, -178.0)})
    assert fitted == ["external_load", "friction_asymmetry", "pressure_dependent_friction"]
    # nothing explains the recording: every leading family is fitted, the stateless first
    fitted, _ = _confirm_with_stand_in_fits(
        ["heat_transfer", "valve_dynamics", "external_load"],
        {"external_load": (25.0, 10.0), "heat_transfer": (19.0, 20.0), "valve_dynamics": (8.5, 60.0)})
    assert fitted == ["external_load", "heat_transfer", "valve_dynamics"]


def test_confirm_from_data_sheet_fits_the_leaders_lookalikes_when_nothing_is_kept():
    """With no leading family kept, the look-alikes of the leader are fitted, as around a nominal optimum
    (practice2_14: the load led, was not kept, and the true pressure-dependent friction, its look-alike
    screened ninth, was never fitted)."""
    fitted, _ = _confirm_with_stand_in_fits(
        ["external_load", "valve_deadband", "heat_transfer", "friction_asymmetry",
                      "pressure_dependent_friction"],
        {"external_load": (29.0, -1.0), "valve_deadband": (29.5, -2.0), "heat_transfer": (28.5, -0.5),
         "friction_asymmetry": (29.9, 0.5), "pressure_dependent_friction": (1.0, 97.0)})
    assert fitted[:3] == ["external_load", "valve_deadband", "heat_transfer"]
    assert "pressure_dependent_friction" in fitted


def test_candidate_outclassed_on_the_window_is_left_to_the_screening_on_top():
    """Once a candidate is kept, one whose pre-fit on the window ends more than ``RIVAL_WINDOW`` times above
    the kept one's is not fitted whole but left to the screening on top of the first finding (practice2_03:
    heat transfer and the spool lag at 4.4 and 7.0 times the dead band's, 326 s of whole fits that lost),
    the kept one's look-alikes too (practice2_25: heat transfer and the supply line at 3.7 and 9.6 times a
    leak's, 84 s, -414 and -337 %); a rival within the factor is fitted."""
    from pneusim.diagnosis import rules

    outcome = {"valve_deadband": (2.0, 96.8), "heat_transfer": (20.0, -368.0), "valve_dynamics": (25.0, -684.0),
               "valve_offset": (28.0, 5.0), "leakage": (21.0, -2.0)}
    window = {"valve_deadband": 1.64, "heat_transfer": 7.13, "valve_dynamics": 11.5, "valve_offset": 23.5,
              "leakage": 4.5}
    second_only = {}
    fitted, trials = _confirm_with_stand_in_fits(
        ["valve_deadband", "leakage", "heat_transfer", "valve_dynamics", "valve_offset"], outcome,
        window=window, second_only=second_only)
    assert fitted == ["valve_deadband", "leakage"]
    assert sorted(second_only) == ["valve_dynamics", "valve_offset"]
    assert trials["valve_offset"].status.startswith("not fitted alone")
    assert trials["valve_dynamics"].status.startswith("not fitted alone") and not trials["valve_dynamics"].kept
    # the factor is what decides: at 2.9 times the kept one's, the spool lag is fitted
    second_only = {}
    window["valve_dynamics"] = (rules.RIVAL_WINDOW - 0.1) * window["valve_deadband"]
    fitted, _ = _confirm_with_stand_in_fits(
        ["valve_deadband", "leakage", "heat_transfer", "valve_dynamics", "valve_offset"], outcome,
        window=window, second_only=second_only)
    assert "valve_dynamics" in fitted and sorted(second_only) == ["valve_offset"]


def test_first_round_defers_a_candidate_without_states_far_behind_on_the_window():
    """Effects without states are fitted first, except one whose pre-fit on the window ends more than
    ``DEFER_WINDOW`` times above the round's best: practice2_27 (a supply line, window rms 1.0) fitted a dead
    band and a load at 7.3 and 7.4 first, 185 s that lost; on practice2_15 the load, 3.1 times behind heat
    transfer on the window, was the truth and is still fitted first."""
    from pneusim.diagnosis import rules

    outcome = {"supply_pressure_droop": (1.0, 99.5), "valve_deadband": (20.0, 77.0), "external_load": (21.0, 78.0)}
    fitted, _ = _confirm_with_stand_in_fits(
        ["supply_pressure_droop", "valve_deadband", "external_load"], outcome,
        window={"supply_pressure_droop": 1.0, "valve_deadband": 7.3, "external_load": 7.36})
    assert fitted == ["supply_pressure_droop"]
    # within the factor the cheaper fits go first, as on practice2_15
    outcome = {"external_load": (1.0, 99.8), "heat_transfer": (19.0, -126.0), "valve_dynamics": (8.5, -178.0)}
    window = {"heat_transfer": 2.34, "valve_dynamics": 5.0, "external_load": 7.3}
    fitted, _ = _confirm_with_stand_in_fits(["heat_transfer", "valve_dynamics", "external_load"],
                                            outcome, window=window)
    assert fitted == ["external_load"]
    assert window["external_load"] < rules.DEFER_WINDOW * window["heat_transfer"]


def test_whole_fit_starts_from_the_data_sheet_where_the_pre_fit_explained_little():
    """A whole fit from the data sheet starts from its pre-fit's nominal values only where that pre-fit
    explained the window (its residual rms within PREFIT_START of the nominal model's there); else from the
    data sheet with the effect's pre-fitted values (practice2_16: the asymmetry's pre-fit at 13.5 times the
    noise against the nominal 13.6, a mass of 1.65 kg against 0.84 kg true; its whole fit from there ended
    at 87.1 %, from the data sheet at 99.46 %)."""
    from pneusim.diagnosis import rules

    starts = {}
    _confirm_with_stand_in_fits(
        ["friction_asymmetry", "valve_offset"],
        {"friction_asymmetry": (20.0, 50.0), "valve_offset": (25.0, 20.0)},
        window={"friction_asymmetry": 13.5, "valve_offset": 4.0}, window_nominal_rms=13.6, starts=starts)
    assert starts["friction_asymmetry"] is None
    assert starts["valve_offset"] == {"moving_mass_kg": 1.65}
    assert 4.0 <= rules.PREFIT_START * 13.6 < 13.5


def _findings_on_top_with_stand_ins(explained: dict, second_only: tuple = (), first_rms: float = 3.0,
                                    warm_finds: bool = True):
    """:func:`add_findings` with stand-in screening and refits: the leak is the first finding (rms
    ``first_rms`` in noise units), ``explained[effect]`` the share of its residual that effect's screening on
    top explains; a refit ends at rms 1 (and passes the test) only with the friction asymmetry in (and, warm
    from the leak's fit, only when ``warm_finds``), else at the leak's own rms.  Fits from the data sheet are
    recorded as ``"EFFECT from the data sheet"``.  Returns the effects refitted, in order, the findings and
    the trials."""
    from pneusim.diagnosis.findings import add_findings

    n = 1000
    refitted = []

    def stand_in_screen(fit, recording, candidate, noise, samples=None):
        base = fit.rms ** 2 * n
        return {"cost": base if candidate is None else base * (1 - explained[candidate.name])}

    def stand_in_refit(recording, rig, effects, warm, start_values=None, label=""):
        refitted.append(effects[-1].name + label)
        found = "friction_asymmetry" in [e.name for e in effects] and (warm_finds or label)
        rms = 1.0 if found else first_rms
        return StandInFit(rms, 99.0 if rms < 2 else 90.0, effects, n=n)

    def stand_in_fit(recording, rig, effects, validation_fraction, start_values=None):
        return stand_in_refit(recording, rig, effects, None, label=" from the data sheet")

    names = ["leakage", *(k for k in explained if k not in second_only)]
    refits, trials = {}, {}
    for name in set(names) | set(second_only):
        c = Candidate(name, name, make_effect(name), [])
        trials[name] = CandidateTrial(name, 1.0, "", status="kept", kept=name in names)
        if name in names:
            refits[name] = (StandInFit(first_rms if name == "leakage" else 5.0, 90.0, [c.effect], n=n), c)
    basis = NominalBaseline(NOISE, 30.0 ** 2 * n, n, 0.0, 0.2, 0.3, None)
    run = stand_in_run(basis, trials=trials, refits=refits,
                       second_only={k: Candidate(k, k, make_effect(k), []) for k in second_only},
                       screen=stand_in_screen, refit=stand_in_refit, fit=stand_in_fit,
                       keep_test=lambda c0, c1, n_, k, f0, f1, floor: (c1 < 0.5 * c0, 0.5, "test"))
    run.max_findings = 2
    findings, _ = add_findings(run, names)
    return refitted, [f.effect for f in findings], trials


def test_second_effect_tried_by_what_it_explains_on_top_of_the_first():
    """The candidates for a second effect are refitted on top of the first finding in the order of what
    their screening explains there, not of how well they fitted alone (practice2_21, a leak and a friction
    asymmetry: a valve offset and a load took the two refits on top and the asymmetry was never tried);
    one left out of the whole fits (``second_only``) is tried the same way."""
    explained = {"valve_offset": 0.05, "external_load": 0.03, "friction_asymmetry": 0.6}
    refitted, found, _ = _findings_on_top_with_stand_ins(explained, second_only=("friction_asymmetry",))
    assert refitted[0] == "friction_asymmetry" and found == ["leakage", "friction_asymmetry"]
    # what explains nothing on top is not refitted at all
    refitted, found, trials = _findings_on_top_with_stand_ins(
        {"valve_offset": 0.001, "friction_asymmetry": -0.2})
    assert refitted == [] and found == ["leakage"]
    assert "not refitted" in trials["valve_offset"].status and not trials["valve_offset"].kept
    # at most ON_TOP_REFITS refits on top, those that explain most there first
    refitted, found, trials = _findings_on_top_with_stand_ins(
        {"valve_offset": 0.05, "external_load": 0.04, "friction_asymmetry": 0.02})
    assert refitted == ["valve_offset", "external_load"] and found == ["leakage"]
    assert "not refitted on top" in trials["friction_asymmetry"].status


def test_while_the_findings_leave_physics_unexplained_every_candidate_that_explains_enough_is_refitted_on_top():
    """The cap of ON_TOP_REFITS holds near noise; where the first finding leaves physics unexplained (its
    residual 6 times the noise, its validation fit 90 % against a noise floor of 0.2 points), the search would
    end in ``other``, which says that no vocabulary effect passes on top: every candidate explaining at least
    MIN_EXPLAINED there is tried first, and the third one is what was missing.  One that explains less than
    MIN_EXPLAINED is still not refitted."""
    from pneusim.diagnosis.rules import MIN_EXPLAINED, ON_TOP_REFITS

    explained = {"valve_offset": 0.05, "external_load": 0.04, "friction_asymmetry": 0.02,
                 "heat_transfer": MIN_EXPLAINED / 2}
    refitted, found, trials = _findings_on_top_with_stand_ins(explained, first_rms=6.0)
    tried = [r for r in refitted if not r.endswith("from the data sheet")]
    # then the leak alone, warm from the pair: whether the asymmetry is needed or only a better optimum
    assert ON_TOP_REFITS == 2 and tried == ["valve_offset", "external_load", "friction_asymmetry", "leakage"]
    assert found == ["leakage", "friction_asymmetry"]
    assert not any(r.startswith("heat_transfer") for r in refitted)


def test_second_effect_fitted_from_the_data_sheet_where_the_first_finding_ends_far_above_noise():
    """Where the first finding's fit ends more than MODEL_SHORT times above the noise and the refit on top of it
    fails the test, the findings and the candidate are fitted together from the data sheet, and that fit is
    tested (practice2_21, a leak at 10.9 times the noise: the friction asymmetry refitted warm on top ended at
    a factor of 0.95 or 1.36, both from the data sheet at 2.07 and 97.1 %).  Near noise it is not tried."""
    from pneusim.diagnosis.rules import MODEL_SHORT

    explained = {"friction_asymmetry": 0.3}
    refitted, found, trials = _findings_on_top_with_stand_ins(
        explained, second_only=("friction_asymmetry",), first_rms=2 * MODEL_SHORT, warm_finds=False)
    # the warm refit, then both from the data sheet, then the leak alone from there (_second_effect_needed)
    assert refitted == ["friction_asymmetry", "friction_asymmetry from the data sheet", "leakage"]
    assert found == ["leakage", "friction_asymmetry"] and trials["friction_asymmetry"].kept
    assert "both fitted from the data sheet" in trials["friction_asymmetry"].status
    # the first finding within MODEL_SHORT of the noise: the warm refit alone decides
    refitted, found, trials = _findings_on_top_with_stand_ins(
        explained, second_only=("friction_asymmetry",), first_rms=0.8 * MODEL_SHORT, warm_finds=False)
    assert refitted == ["friction_asymmetry"] and found == ["leakage"]
    assert not trials["friction_asymmetry"].kept


def test_fit_from_the_data_sheet_above_the_nominal_residual_is_retried_from_the_nominal_fit():
    """Far above noise too, a whole fit from the data sheet that ends above the nominal fit's residual is
    fitted again from the effect's neutral value warm from the nominal fit, and the lower one is tested
    (practice2_16: the true friction asymmetry's fit from the data sheet ended at 13.8 times the noise,
    above the nominal 13.5); an effect without a neutral value (heat transfer) is not retried."""
    fitted, trials = _confirm_with_stand_in_fits(
        ["heat_transfer", "friction_asymmetry"],
        {"heat_transfer": (31.0, -5.0), "friction_asymmetry": (31.0, -3.0)},
        retried={"friction_asymmetry": (2.0, 98.0)})
    assert fitted == ["friction_asymmetry", "friction_asymmetry from the nominal fit", "heat_transfer"]
    assert trials["friction_asymmetry"].kept and trials["friction_asymmetry"].fit_percent == 98.0
    assert "again from the neutral value" in trials["friction_asymmetry"].status
    assert not trials["heat_transfer"].kept and "neutral" not in trials["heat_transfer"].status
    # once a kept fit explains the recording down to the noise, a rival is not retried
    fitted, trials = _confirm_with_stand_in_fits(
        ["external_load", "friction_asymmetry"],
        {"external_load": (1.0, 99.8), "friction_asymmetry": (31.0, -3.0)}, retried={"friction_asymmetry": (1.1, 99.7)})
    assert fitted == ["external_load", "friction_asymmetry"]


def _second_effect_with_stand_ins(alone_rms: float, alone_fit: float):
    """:func:`_second_effect_needed` on stand-in fits: the leak alone at 3 times the noise (94.5 %), the leak
    with a valve offset on top at 1.0 (99.87 %), and the leak refitted alone from there at ``alone_rms``."""
    from pneusim.diagnosis.findings import _second_effect_needed
    from pneusim.diagnosis.result import Finding

    n = 5600
    calls = []

    def stand_in_refit(recording, rig, effects, warm, start_values=None):
        calls.append(([e.name for e in effects], warm))
        return StandInFit(alone_rms, alone_fit, effects, n=n)

    leak = make_effect("leakage")
    final = StandInFit(3.0, 94.5, [leak], n=n)
    fit2 = StandInFit(1.0, 99.87, [leak, make_effect("valve_offset")], n=n)
    trials = {"leakage": CandidateTrial("leakage", 1.0, "ev", status="kept"),
              "valve_offset": CandidateTrial("valve_offset", 1.0, "ev", status="kept")}
    findings = [Finding(effect="leakage", evidence="ev", parameters={}, fit_percent=94.5, improvement_points=245.0)]
    run = stand_in_run(NominalBaseline(NOISE, math.nan, n, math.nan, 0.15, 0.3, None), trials=trials,
                       refit=stand_in_refit)
    needed, new_final = _second_effect_needed(run, final, final.rms ** 2 * n, fit2, fit2.rms ** 2 * n,
                                              "valve_offset", 1, findings)
    assert calls == [(["leakage"], fit2)]     # the findings before it, warm from the refit on top
    return needed, new_final, final, findings


def test_second_effect_whose_gain_was_the_optimisers_is_not_kept():
    """A refit on top runs the optimiser on from the first finding's optimum with one more parameter: where
    the first effect alone, refitted warm from there, does as well, the second effect is not needed, and the
    first finding is rebuilt on that better optimum (practice_09: a leak alone, a 0.4 mV offset "on top")."""
    needed, new_final, final, findings = _second_effect_with_stand_ins(1.0, 99.86)
    assert not needed and new_final is not final and new_final.fit_percent == 99.86
    assert findings[0].fit_percent == 99.86 and findings[0].improvement_points == pytest.approx(245.0 + 5.36)
    # the second effect is needed where the first alone stays short of it
    needed, new_final, final, findings = _second_effect_with_stand_ins(2.9, 94.6)
    assert needed and new_final is final and findings[0].fit_percent == 94.5


def test_second_effect_stands_where_the_first_had_not_stopped_short():
    """Where the first effect refitted alone from the optimum with both ends above its own fit on the
    estimation part, that fit had not stopped short: the test the second effect passed against it stands,
    even when the refit alone validates nearly as well as both (practice2_09: a load and friction
    asymmetry, the load refitted alone at 98.91 % against 99.35 % with both, 0.06 points short of 0.50)."""
    needed, new_final, final, findings = _second_effect_with_stand_ins(3.2, 99.8)
    assert needed and new_final is final and findings[0].fit_percent == 94.5


def _grown_with_stand_ins(before_rms: float, warm: tuple, sheet: tuple, warm_start: bool = True):
    """:func:`_grown_from_data_sheet` on stand-in fits: a spool lag and a load fitted at ``before_rms`` (noise units),
    a leak grown on top warm from them ending at ``warm`` = (rms, validation %), the three from the data sheet at
    ``sheet``.  Returns the fit kept, the fits from the data sheet asked for (their effects) and the leak's trial."""
    from pneusim.diagnosis.findings import _grown_from_data_sheet

    n = 1000
    asked = []

    def stand_in_fit(recording, rig, effects, validation_fraction, start_values=None):
        asked.append([e.name for e in effects])
        return StandInFit(*sheet, effects, n=n)

    pair = [make_effect("valve_dynamics"), make_effect("external_load")]
    before = StandInFit(before_rms, -200.0, pair, n=n)
    grown = StandInFit(*warm, pair + [make_effect("leakage")], n=n)
    grown.solver = {"warm_start": warm_start}
    trials = {"leakage": CandidateTrial("leakage", 1.0, "ev", status="kept")}
    run = stand_in_run(NominalBaseline(NOISE, 30.0 ** 2 * n, n, -500.0, 0.2, 0.3, None), trials=trials,
                       fit=stand_in_fit)
    leak = Candidate("leakage", "leakage", make_effect("leakage"), [])
    kept, cost = _grown_from_data_sheet(run, before, leak, grown, warm[0] ** 2 * n)
    assert cost == pytest.approx(kept.rms ** 2 * n)
    return kept, grown, asked, trials["leakage"]


def test_a_set_grown_on_a_fit_far_above_noise_is_fitted_again_from_the_data_sheet():
    """A set grown by one effect, warm from a fit that ended more than MODEL_SHORT times above the noise, that
    still leaves physics unexplained is fitted again from the data sheet, and the lower on the estimation part is
    the findings' fit from there on (practice3_28, a spool lag and a load at -200 %, a leak on top warm at
    -101 %: the three from the data sheet reach the noise, 91 %).  Not tried where the fit it grew from was near
    the noise, where the grown set explains the recording, or where the grown set already came from the data
    sheet."""
    from pneusim.diagnosis.rules import MODEL_SHORT

    far = 2 * MODEL_SHORT
    kept, grown, asked, trial = _grown_with_stand_ins(far, (8.0, -100.0), (1.1, 91.0))
    assert asked == [["valve_dynamics", "external_load", "leakage"]] and kept is not grown
    assert kept.fit_percent == 91.0 and "fitted from the data sheet ends lower" in trial.status
    # the data sheet's fit ends higher: the warm refit stays, and the status says so
    kept, grown, asked, trial = _grown_with_stand_ins(far, (8.0, -100.0), (9.0, -150.0))
    assert len(asked) == 1 and kept is grown and "the warm refit stays" in trial.status
    # not tried: the fit it grew from near the noise; the grown set at noise; the grown set from the data sheet
    for before_rms, warm, warm_start in ((0.8 * MODEL_SHORT, (8.0, -100.0), True), (far, (1.0, 99.5), True),
                                         (far, (8.0, -100.0), False)):
        kept, grown, asked, trial = _grown_with_stand_ins(before_rms, warm, (1.1, 91.0), warm_start)
        assert asked == [] and kept is grown and "data sheet" not in trial.status
