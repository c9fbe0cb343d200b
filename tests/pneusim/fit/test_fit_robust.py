"""The fit says when it ends above noise, warm-started refits, and the robustness set's hardest kinds.

* A recording with a valve dead band fitted by the nominal model cannot reach the sensor noise: the
  result says so (normalised residual, ``converged_to_noise``, ``success`` false, a warning) and
  ``pneusim fit`` exits with status 3.
* The refit with the dead band switched on, warm-started from that nominal fit (diagnosis's use),
  reaches the noise level and recovers the dead band.
* Seeded recordings of the robustness set's hardest kinds (:func:`pneusim.fit.robustness.hardest_cases`),
  fitted with the friction smoothing velocity freed beside the seven defaults (see
  :mod:`pneusim.fit.robustness` for why): the fit reaches the noise level and the truth lies within
  3 sigma for at least six of the seven default parameters.  7 of the 8 pass (85 s with two
  workers); ``s5000`` still ends above noise and is marked as a strict expected failure.
* Cases of the robustness set whose fits are chaotic in their start (the landing basin of a trust region or
  a filter hangs on the last bits of the arithmetic): the *verdict* is asserted (the fit reaches the noise,
  the truth within 3 sigma), never the route that got there, and for the cheaper ones also with the start
  values or the data moved by 1e-12 relative (``verdicts.py``); ``.ci/run`` runs them again under a second
  arithmetic path.  A closed-loop multisine whose first start ends above noise (``s1041``), a recording that
  starts mid stick-slip with end stops (``s5006``), open-loop stick-slip with both pressures (``s1026``) and
  without (``s1027``), pulses whose pre-fit may stall above noise (``s1033``), and a chaotic multisine the
  prediction-error route brings to the noise (``s1030``).
* At the true parameters the filter's starts bring a chaotic window (``s1007``) from 8.3 times noise (chained
  starts) to the noise, the filter's whitened innovations are white, and least squares on them from the data
  sheet's values recover every parameter of a chaotic recording (``s1030``).
* The chaotic open-loop ``s1007`` fitted from its true values reaches the noise.
* A recording whose piston rests at its end stop through the first pre-fit window (``s1018``): the window
  moves to where the piston moves, and the fit reaches the noise.
* The trust region starts a fresh region after a stop on its step tolerance alone above noise.
* The robustness score counts a parameter whose standard error is not finite as outside 3 sigma.
"""

import json

import numpy as np
import pytest

from pneusim.cli import main
from pneusim.experiment import standard_experiment
from pneusim.fit import fit_recording
from pneusim.fit.setup import FitSetup
from pneusim.fit.initial import initial_starts
from pneusim.fit.prediction_error import prediction_error_fit
from pneusim.fit.tracking import filtered_states, process_std, run_filter
from pneusim.fit.rules import ABOVE_NOISE_WARNING, FAR_ABOVE_NOISE, INFORMATIVE_WINDOW
from pneusim.fit.robustness import fit_free, hardest_cases, make_case, robustness_cases, score
from pneusim.model import make_effect
from pneusim.recording import write_recording
from pneusim.rig import load_rig
from pneusim.simulate import simulate
from verdicts import assert_verdict, fits_under_perturbations

DEADBAND_V = 0.3


@pytest.fixture(scope="module")
def deadband_case(tmp_path_factory):
    rig = load_rig("paper2-enfield")
    true_rig = rig.with_params({"moving_mass_kg": 1.2 * rig["moving_mass_kg"],
                                "friction_coulomb_N": 0.9 * rig["friction_coulomb_N"]})
    exp = standard_experiment(true_rig, "pulses", 20.0, "open", seed=5)
    rec = simulate(true_rig, exp, [make_effect("valve_deadband", deadband_V=DEADBAND_V)], seed=6).recording
    path = tmp_path_factory.mktemp("deadband") / "deadband.csv"
    write_recording(rec, path)
    return rig, rec, path


@pytest.fixture(scope="module")
def nominal_fit(deadband_case):
    rig, rec, _ = deadband_case
    return fit_recording(rec, rig, quiet=True)


@pytest.mark.slow
def test_nominal_fit_of_a_dead_band_recording_says_it_is_above_noise(nominal_fit, tmp_path):
    result = nominal_fit
    assert result.normalised_residual > FAR_ABOVE_NOISE
    assert result.normalised_residual == max(result.normalised_residuals.values())
    assert not result.converged_to_noise
    assert any("above the sensor noise" in w for w in result.warnings)
    data = json.loads(result.write_json(tmp_path / "fit.json").read_text())
    assert data["converged_to_noise"] is False and data["success"] is False
    assert data["solver"]["success"] is False
    assert data["normalised_residual"] == pytest.approx(result.normalised_residual)


@pytest.mark.slow
def test_warm_refit_with_the_missing_effect_reaches_noise(deadband_case, nominal_fit):
    rig, rec, _ = deadband_case
    refit = fit_recording(rec, rig, [make_effect("valve_deadband")], warm_start=nominal_fit, quiet=True)
    assert refit.solver["warm_start"] is True
    assert refit.converged_to_noise and refit.normalised_residual < ABOVE_NOISE_WARNING
    assert refit.warnings == [] or not any("above the sensor noise" in w for w in refit.warnings)
    p = refit.parameters["valve_deadband.deadband_V"]
    assert np.isfinite(p.std) and abs(p.estimate - DEADBAND_V) <= 3.0 * p.std and abs(p.estimate / DEADBAND_V - 1.0) < 0.05
    # the nominal parameters start from the nominal fit's values, not from the data sheet
    assert p.start == pytest.approx(0.2)
    assert refit.parameters["moving_mass_kg"].start == pytest.approx(nominal_fit.estimates["moving_mass_kg"])


@pytest.mark.slow
def test_start_values_override_the_warm_start(deadband_case, nominal_fit):
    """Diagnosis starts a refit's friction levels where its screening left them: the named values
    replace the warm fit's, the refit still reaches noise, and an unknown name is refused."""
    from pneusim.errors import FitError

    rig, rec, _ = deadband_case
    moved = 0.8 * nominal_fit.estimates["friction_coulomb_N"]
    refit = fit_recording(rec, rig, [make_effect("valve_deadband")], warm_start=nominal_fit,
                          start_values={"friction_coulomb_N": moved}, quiet=True)
    assert refit.parameters["friction_coulomb_N"].start == pytest.approx(moved)
    assert refit.converged_to_noise and refit.normalised_residual < ABOVE_NOISE_WARNING
    with pytest.raises(FitError, match="start_values: unknown parameter 'friction_kinetic_N'"):
        fit_recording(rec, rig, warm_start=nominal_fit, start_values={"friction_kinetic_N": 1.0}, quiet=True)


def test_prefit_alone_tells_the_missing_effect_from_the_data_sheet(deadband_case):
    """The pre-fit alone (diagnosis's screening far above noise): from the data sheet, with the dead band
    on, the first 2000 samples are explained down to about the noise and the dead band comes back; the
    nominal model's pre-fit on the same window stays far above noise."""
    from pneusim.fit import prefit_recording

    rig, rec, _ = deadband_case
    nominal = prefit_recording(rec, rig, [], second_route=False, max_evaluations=40)
    with_it = prefit_recording(rec, rig, [make_effect("valve_deadband", deadband_V=0.02)], second_route=False,
                               max_evaluations=40)
    assert nominal.samples == with_it.samples == min(2000, int(round(0.7 * rec.n_samples)))
    assert nominal.normalised_residual > FAR_ABOVE_NOISE
    assert with_it.normalised_residual < 1.2 and with_it.cost < 0.5 * nominal.cost
    assert with_it.estimates["valve_deadband.deadband_V"] == pytest.approx(DEADBAND_V, rel=0.05)


@pytest.mark.slow
def test_warm_start_from_another_recording_is_refused(deadband_case, nominal_fit):
    from pneusim.errors import FitError

    rig, rec, _ = deadband_case
    shorter = rec.slice(None, rec.time_s[int(0.8 * rec.n_samples)])
    with pytest.raises(FitError, match="warm_start must be a fit of this recording"):
        fit_recording(shorter, rig, warm_start=nominal_fit, quiet=True)


@pytest.mark.slow
def test_cli_exits_3_far_above_noise(deadband_case, tmp_path, capsys):
    _, _, path = deadband_case
    out = tmp_path / "fit.json"
    assert main(["fit", str(path), "--json", str(out), "--quiet"]) == 3
    data = json.loads(out.read_text())
    assert data["converged_to_noise"] is False and data["normalised_residual"] > FAR_ABOVE_NOISE
    err = capsys.readouterr().err
    assert "exit status 3" in err and "Traceback" not in err


#: the one hardest case that still fails (issue 9's targets, 95 % of the robustness set at noise, are met
#: without it): its first pre-fit ends at 3.46 times noise in a basin of another friction shape (static
#: friction 954 N against 47 N true, Stribeck velocity 1.9 mm/s against 16, smoothing 17 mm/s against 0.63),
#: its other starts at 5.4 and 6.2; from the truth the fit ends at 1.03.  Strict: the day it passes, this
#: mark must go.
OPEN_HARDEST = {"paper2-enfield-steps-closed-x-s5000": "known failure: ends at 3.6 times noise in a wrong "
                "friction basin; from the truth 1.03"}


def _hardest_params():
    return [pytest.param(spec, id=spec.name, marks=[pytest.mark.minutes]
                         + ([pytest.mark.xfail(reason=OPEN_HARDEST[spec.name], strict=True)]
                            if spec.name in OPEN_HARDEST else []))
            for spec in hardest_cases(8)]


@pytest.mark.parametrize("spec", _hardest_params())
def test_hardest_kinds_reach_noise_with_truth_inside_three_sigma(spec):
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    s = score(result, truth)
    assert result.converged_to_noise, (result.normalised_residuals, result.solver["prefit_attempts"])
    assert s["inside_3_sigma"] >= s["parameters"] - 1, s["z"]


@pytest.mark.minutes
def test_closed_loop_multisine_whose_first_start_ends_above_noise_reaches_noise():
    """Paper 1, closed-loop multisine without pressures (``s1041`` of the robustness set): the first start's fit
    ends above noise (its pre-fit at about twice the noise, the Stribeck velocity far off), and the fit goes on
    (the prediction-error route, the next start) until it reaches the noise with the truth within 3 sigma: as
    given and with the start values or the data moved by 1e-12 relative."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1041)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper1-mre", "multisine", "closed", False)
    rig, truth, rec = make_case(spec)
    for label, result in fits_under_perturbations(rec, rig, free=fit_free(True)):
        assert result.solver["prefit_attempts"][0]["rms_normalised"] > ABOVE_NOISE_WARNING
        assert_verdict(result, truth, label)


@pytest.mark.minutes
def test_recording_starting_mid_stick_slip_with_stops_reaches_noise():
    """Paper 2, open-loop steps without pressures (``s5006`` of the hardest set, run by default): the
    recording starts mid stick-slip and spends a fifth of its samples at the end stop.  Before the
    first state was searched again at the pre-fit's parameters and the model position compared with
    the mean reading of a sensor saturating at the stroke, this fit ended at 2.05 times noise even
    from the truth (now 0.92, all seven truths within 3 sigma)."""
    spec = next(s for s in hardest_cases(8) if s.seed == 5006)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "steps", "open", False)
    rig, truth, rec = make_case(spec)
    assert abs(rec.position_m - rig.stroke_m).min() == 0.0  # saturated readings at the stop
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    s = score(result, truth)
    assert result.converged_to_noise, result.normalised_residuals
    assert s["inside_3_sigma"] >= s["parameters"] - 1, s["z"]


@pytest.mark.slow
def test_prefit_window_moves_to_where_a_piston_resting_at_its_stop_starts_to_move():
    """Paper 1, open-loop multisine with pressures (``s1018`` of the robustness set): the piston rests at
    its end stop for the first 3.3 s, the whole first 2000-sample window.  A pre-fit there says nothing about
    friction and mass (it ended at noise with the conductance at 0.52 and the Coulomb friction at 2.1 times the
    truth).  The window moves to where the piston moves, and the fit reaches the noise with every truth within
    3 sigma.  A recording that moves from its start keeps the first window."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1018)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper1-mre", "multisine", "open", True)
    rig, truth, rec = make_case(spec)
    setup = FitSetup(rec, rig, (), fit_free(True), None, None, None, 50)
    start = setup.prefit_start(2000)
    assert np.ptp(rec.position_m[:2000]) < INFORMATIVE_WINDOW * np.ptp(rec.position_m[:setup.n_est])
    assert start > 0 and start % setup.seg == 0 and start + 2000 <= setup.n_est
    assert np.ptp(rec.position_m[start:start + 2000]) == np.ptp(rec.position_m[:setup.n_est])
    moving = next(s for s in robustness_cases(48) if s.seed == 1016)   # paper 1, closed-loop multisine
    moving_rig, _, moving_rec = make_case(moving)
    assert FitSetup(moving_rec, moving_rig, (), fit_free(True), None, None, None, 50).prefit_start(2000) == 0

    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    assert result.solver["prefit_attempts"][0]["window_start_sample"] == start
    assert_verdict(result, truth, all_inside=True)


def test_trust_region_starts_afresh_after_a_stall_on_its_step_tolerance_above_noise():
    """SciPy's step tolerance is relative to the norm of all variables, which the segment states dominate: a
    region shrunk in the penalty's curved valley stops a run while the cost still falls.  Where a run stops on
    that tolerance alone above noise, the trust region starts afresh from there, ``restarts`` times at most;
    not after a stop at noise, nor on the cost tolerance (SciPy replaced by a stand-in that lowers the residual
    by a tenth per run and says how it stopped)."""
    from types import SimpleNamespace

    from pneusim.fit.trust_region import trust_region

    class Problem:                       # one residual value repeated: the normalised rms is |v[0]|
        n_residuals, n_constraints = 100, 0

        def evaluate(self, v, derivatives=True):
            return {"ok": True, "r": np.full(100, v[0]), "g": np.zeros(0)}

    def runs(v0, status, restarts=1):
        starts = []

        def least_squares(fun, x0, **options):
            starts.append(float(x0[0]))
            return SimpleNamespace(x=0.9 * x0, nfev=5, njev=5, status=status)

        v, rms, info = trust_region(Problem(), np.array([v0]), np.array([-10.0]), np.array([10.0]),
                                    restarts=restarts, least_squares=least_squares)
        assert info["restarts"] == len(starts) - 1 and rms == pytest.approx(abs(v[0]))
        return starts

    assert runs(2.0, 3) == pytest.approx([2.0, 1.8])            # above noise on the step tolerance: once more
    assert runs(2.0, 3, restarts=2) == pytest.approx([2.0, 1.8, 1.62])
    assert runs(1.1, 3) == [1.1]                                  # at noise (0.99): done
    assert runs(2.0, 4) == [2.0]                                  # the cost no longer falls: done
    assert runs(2.0, 3, restarts=0) == [2.0]


@pytest.mark.slow
def test_pulses_whose_prefit_may_stall_above_noise_reach_noise():
    """Paper 2, closed-loop pulses without pressures (``s1033`` of the robustness set): the pre-fit's trust
    region may stop on SciPy's step tolerance above noise (about twice the noise, with the conductance 13 %
    off), or reach the noise after a fresh region, as the last bits of its arithmetic fall; either way the fit
    reaches the noise with every truth within 3 sigma: as given and with the start values or the data moved by
    1e-12 relative."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1033)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "pulses", "closed", False)
    rig, truth, rec = make_case(spec)
    for label, result in fits_under_perturbations(rec, rig, free=fit_free(True)):
        assert_verdict(result, truth, label, all_inside=True)


@pytest.mark.minutes
def test_fit_started_at_the_truth_of_a_chaotic_open_loop_recording_stays_at_noise():
    """Paper 2, open-loop multisine without pressures (``s1007`` of the robustness set), started at its eight
    true values.  The piston stick-slips from sample to sample, and at the truth the segments started from
    the chained simulation leave the recorded slip pattern within seconds (their own samples at 3-20 times
    noise from the ninth segment on), so the shooting fit from there ends above noise with the parameters off;
    the fit still ends at the noise with the truth within 3 sigma."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1007)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "multisine", "open", False)
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True, start_values=truth)
    assert_verdict(result, truth)


def _window(seed: int, at_truth: bool = False):
    """``(problem of the 2000-sample pre-fit window, setup, truth)`` of robustness case ``seed``, the setup
    starting from the data sheet or from the truth."""
    spec = next(s for s in robustness_cases(48) if s.seed == seed)
    rig, truth, rec = make_case(spec)
    setup = FitSetup(rec, rig, (), fit_free(True), None, None, truth if at_truth else None, 50)
    pb, _, _ = setup.problem(2000, 1e-6, 1)
    return pb, setup, truth


@pytest.mark.slow
def test_filtered_starts_follow_a_chaotic_recording_at_its_true_parameters():
    """Paper 2, open-loop multisine without pressures (``s1007``), its 2000-sample pre-fit window at the
    true parameters: segments started from the chained simulation leave the recorded slip pattern (the
    window at 8.3 times noise), segments started from the extended Kalman filter's states follow it (a
    model at its true parameters, corrected by every position sample, must track the recording to the
    noise: 0.90)."""
    pb, setup, _ = _window(1007, at_truth=True)
    theta = setup.theta_start

    def window_rms(starts):
        e = pb.evaluate(pb.join(theta, starts), derivatives=False)
        return float(np.sqrt(np.mean(e["r"] ** 2)))

    chained = initial_starts(pb, theta, setup.recording, pb.data.n_samples)
    filtered = filtered_states(pb, theta, chained[0])
    rms_chained, rms_filtered = window_rms(chained), window_rms(filtered[pb.starts])
    pb.close()
    assert filtered.shape == (2000, pb.n) and np.all(np.isfinite(filtered))
    assert rms_chained > 5.0
    assert rms_filtered < ABOVE_NOISE_WARNING


@pytest.mark.slow
def test_filter_innovations_are_white_at_the_true_parameters():
    """At the true parameters the filter predicts each sample to within its own predicted uncertainty: the
    whitened innovations of ``s1030``'s window (paper 2, open-loop multisine, both pressures, a chaotic
    stick-slip) have rms 1 to within 15 % and no trend; at the data sheet's values (tens of percent off)
    they are far above it.  Their fixed-gain Jacobian has one row per measured value and a column per free
    parameter and first state."""
    pb, setup, truth = _window(1030)
    theta_true = np.array([truth[name] for name in setup.free]) / setup.scales
    first = initial_starts(pb, theta_true, setup.recording, pb.data.n_samples)[0]
    process = process_std(pb, 3e-4)
    at_truth = run_filter(pb, theta_true, first, process, gradients=True)
    at_sheet = run_filter(pb, setup.theta_start, first, process, gradients=True)
    pb.close()
    e = at_truth["innovations"]
    assert at_truth["ok"] and e.shape == (2000 * 3,)
    assert at_truth["jacobian"].shape == (2000 * 3, pb.n_free + pb.n)
    assert 0.85 < np.sqrt(np.mean(e ** 2)) < 1.15
    halves = e.reshape(2, -1)
    assert np.all(np.abs(np.sqrt(np.mean(halves ** 2, axis=1)) - 1.0) < 0.2)
    assert np.sqrt(np.mean(at_sheet["innovations"] ** 2)) > 3.0


@pytest.mark.slow
def test_prediction_error_fit_recovers_a_chaotic_recording_from_the_data_sheet():
    """``s1030``: every pre-fit of the shooting problem from the data sheet ends more than five times above
    noise.  Least squares on the filter's innovations from the same start end at the noise level with all
    eight free parameters (the friction smoothing velocity too) within 5 % of the truth."""
    pb, setup, truth = _window(1030)
    first = initial_starts(pb, setup.theta_start, setup.recording, pb.data.n_samples)[0]
    theta, _, info = prediction_error_fit(pb, setup.theta_start, first, setup.lower, setup.upper)
    pb.close()
    estimates = dict(zip(setup.free, theta * setup.scales))
    errors = {name: estimates[name] / truth[name] - 1.0 for name in setup.free}
    assert info["rms_innovations"] < ABOVE_NOISE_WARNING, info
    assert max(abs(e) for e in errors.values()) < 0.05, errors


@pytest.mark.minutes
def test_chaotic_fit_reaches_noise_through_the_prediction_error_route():
    """``s1030`` fitted from the data sheet: the shooting fit ends far above noise (the pre-fits around five times
    it, 9.7 times after the whole fit before the prediction-error route existed); the prediction-error route is
    kept and the fit reaches the noise with every truth within 3 sigma."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1030)
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    route = result.solver["prediction_error_route"]
    assert route is not None and route["kept"], (route, result.solver["prefit_attempts"])
    assert_verdict(result, truth, all_inside=True)


@pytest.mark.minutes
def test_chaotic_open_loop_steps_reach_noise():
    """Paper 2, open-loop steps without pressures (``s1027`` of the robustness set): the piston stick-slips from
    sample to sample through every slow motion, and the fits from the data sheet's starts end above noise in
    basins that differ with the last bits of the arithmetic (1.6-2.4 times noise, the Stribeck velocity and the
    viscous friction at half the truth).  The fit reaches the noise with the truth within 3 sigma anyway, by
    whichever route (segment starts tracked by the Kalman filter, the prediction-error route): as given and with
    the start values or the data moved by 1e-12 relative."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1027)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "steps", "open", False)
    rig, truth, rec = make_case(spec)
    for label, result in fits_under_perturbations(rec, rig, free=fit_free(True)):
        assert_verdict(result, truth, label, all_inside=True)


#: the true rig of the open-loop random-steps example: every default free parameter off the data sheet
OPEN_LOOP_TRUTH = {"valve_sonic_conductance_m3_per_s_Pa": 1.36e-08, "valve_critical_pressure_ratio": 0.26,
                   "friction_static_N": 48.0, "friction_coulomb_N": 27.0, "friction_stribeck_velocity_m_per_s": 0.026,
                   "friction_viscous_N_s_per_m": 72.0, "moving_mass_kg": 1.5}


@pytest.mark.minutes
def test_open_loop_random_steps_get_the_verdict_of_what_the_fit_reached():
    """Paper 2, open-loop random steps without pressures, 8000 samples (``pneusim simulate --rig paper2-enfield
    --input steps --loop open --seed 3 --no-pressures`` with the parameters above): the fit reaches the noise
    with every truth within 3 sigma, and the verdict the user reads says so (``success``, no warning), as given
    and with the start values or the data moved by 1e-12 relative.  Its Gauss-Newton settling iterates scatter
    on this stick-slip recording; whether the first few had their defects closed was a draw of the arithmetic,
    and one path handed the same answer to IPOPT, which called it a failure or took a minute and a half."""
    true_rig = load_rig("paper2-enfield").with_params(OPEN_LOOP_TRUTH)
    rec = simulate(true_rig, standard_experiment(true_rig, "steps", 80.0, "open", seed=3), seed=3,
                   record_pressures=False).recording
    for label, result in fits_under_perturbations(rec, load_rig("paper2-enfield")):
        assert_verdict(result, OPEN_LOOP_TRUTH, label, all_inside=True)
        assert result.warnings == [], (label, result.warnings)


@pytest.mark.minutes
def test_open_loop_stick_slip_with_pressures_reaches_noise():
    """Paper 2, open-loop steps with both pressures (``s1026`` of the robustness set): the piston
    stick-slips from sample to sample through slow motion, and the 50-sample pre-fit ends above noise with the
    friction tens of percent off (a fit from there ends at 2.11 times noise, 3 of 7 truths within 3 sigma).
    Through 10-sample segments (the short-segment route) or the rescue routes, the fit reaches the noise with
    every truth within 3 sigma."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1026)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "steps", "open", True)
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    assert_verdict(result, truth, all_inside=True)


def test_expected_reading_of_a_saturating_sensor_matches_monte_carlo():
    """The fit's mean position reading of a sensor whose range ends at 0 and at the stroke: against
    the sample mean of clipped noisy readings, and its slope against finite differences."""
    import numpy as np

    from pneusim.fit.shooting import expected_position_reading

    stroke, sigma = 0.3048, 6.1e-5
    x = np.array([-3 * sigma, 0.0, 2 * sigma, 0.15, stroke - sigma, stroke, stroke + 0.08e-3, stroke + 1e-3])
    mean, slope = expected_position_reading(x, stroke, sigma)
    noise = np.random.default_rng(1).normal(0.0, sigma, 400_000)
    sampled = np.array([np.clip(v + noise, 0.0, stroke).mean() for v in x])
    assert np.allclose(mean, sampled, atol=4 * sigma / np.sqrt(noise.size))
    assert mean[3] == x[3] and mean[-1] == pytest.approx(stroke, abs=1e-12)   # inside: x; far past: the stroke
    h = 1e-9
    numeric = (expected_position_reading(x + h, stroke, sigma)[0] - expected_position_reading(x - h, stroke, sigma)[0]) / (2 * h)
    assert np.allclose(slope, numeric, atol=1e-5)


def test_score_counts_an_unconstrained_parameter_as_outside_three_sigma():
    """A standard error that is not finite (a direction the data did not constrain: the covariance
    says inf) covers nothing.  Dividing by it gave z = 0, and two paper-1 fits stuck at 2.4 and 3.1
    times noise counted 7 of 7 truths inside 3 sigma."""
    from types import SimpleNamespace

    from pneusim.fit import DEFAULT_FREE
    from pneusim.fit.result import ParameterEstimate

    truth = {name: 1.0 for name in DEFAULT_FREE}
    stds = [np.inf, 0.0, np.nan, 0.1, 0.1, 0.01, 0.5][:len(DEFAULT_FREE)]
    estimates = [1.05, 1.0, 1.0, 1.2, 1.4, 1.0, 2.0][:len(DEFAULT_FREE)]
    parameters = {name: ParameterEstimate(name, e, s, 1.0, 0.0, 10.0)
                  for name, e, s in zip(DEFAULT_FREE, estimates, stds)}
    result = SimpleNamespace(parameters=parameters, normalised_residual=2.4, converged_to_noise=False,
                             solver={"seconds": 1.0})
    s = score(result, truth)
    # inside: z = 2 (1.2 +- 0.1), 0 (1.0 +- 0.01), 2 (2.0 +- 0.5); outside: inf, zero and NaN std, z = 4
    assert s["inside_3_sigma"] == 3 and s["parameters"] == 7
    assert all(np.isinf(s["z"][name]) for name in DEFAULT_FREE[:3])
