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
* Three cases of the robustness set run by default: a restart when the first start ends above noise
  (``s1041``), a recording that starts mid stick-slip with end stops (``s5006``), and one with both
  pressures that stick-slips from sample to sample (``s1026``, the short-segment route).
* A chaotic open-loop recording without pressures (``s1027``) reaches the noise through segment starts
  tracked by a Kalman filter after its fit ended above it; at the true parameters the filter's starts
  bring a chaotic window (``s1007``) from 8.3 times noise (chained starts) to the noise.
* The prediction-error route: at the true parameters the Kalman filter's whitened innovations have unit
  rms; least squares on them from the data sheet's values recover every parameter of a chaotic recording
  (``s1030``) whose pre-fits all end more than five times above noise, and the fit then reaches the noise
  through that route.
* The chaotic open-loop ``s1007`` fitted from its true values reaches the noise (a strict expected failure
  at 1.65 times noise until the prediction-error route).
* A recording whose piston rests at its end stop through the first pre-fit window (``s1018``): the window
  moves to where the piston moves, and the fit reaches the noise from its first trust region.
* A pre-fit whose trust region stalls above noise (``s1033``) starts a fresh region from there and reaches
  the noise with the parameters recovered.
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


def test_warm_start_from_another_recording_is_refused(deadband_case, nominal_fit):
    from pneusim.errors import FitError

    rig, rec, _ = deadband_case
    shorter = rec.slice(None, rec.time_s[int(0.8 * rec.n_samples)])
    with pytest.raises(FitError, match="warm_start must be a fit of this recording"):
        fit_recording(shorter, rig, warm_start=nominal_fit, quiet=True)


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
def test_fit_restarts_when_the_first_start_ends_above_noise():
    """Paper 1, closed-loop multisine without pressures (``s1041`` of the robustness set): the first
    start's pre-fit ends at 2.14 and its fit at 2.37 times noise, with the Stribeck velocity at 3.4
    times the truth.  The fit did not restart (it had not ended *well above* its pre-fit); now a fit
    and pre-fit both above noise try the next start, whose fit reaches the noise."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1041)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper1-mre", "multisine", "closed", False)
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    attempts = result.solver["prefit_attempts"]
    assert len(attempts) >= 2 and attempts[0]["fit_rms_normalised"] > 1.1, attempts
    s = score(result, truth)
    assert result.converged_to_noise, (result.normalised_residuals, attempts)
    assert s["inside_3_sigma"] >= s["parameters"] - 1, s["z"]


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


def test_prefit_window_moves_to_where_a_piston_resting_at_its_stop_starts_to_move():
    """Paper 1, open-loop multisine with pressures (``s1018`` of the robustness set): the piston rests at
    its end stop for the first 3.3 s, the whole first 2000-sample window.  The pre-fit there ended at noise
    with the conductance at 0.52 and the Coulomb friction at 2.1 times the truth, the whole part's fit from
    it at 4.2 times noise, and only the continuation route reached the noise (27.6 s).  The window now
    moves to where the piston moves; the fit reaches the noise from the first trust region, every truth
    within 3 sigma.  A recording that moves from its start keeps the first window."""
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
    attempts = result.solver["prefit_attempts"]
    assert attempts[0]["window_start_sample"] == start
    assert len(attempts) == 1 and [r["route"] for r in attempts[0]["fit_routes"]] == ["direct"], attempts
    s = score(result, truth)
    assert result.converged_to_noise, result.normalised_residuals
    assert s["inside_3_sigma"] == s["parameters"], s["z"]


def test_prefit_starts_afresh_where_its_trust_region_stalls_above_noise():
    """Paper 2, closed-loop pulses without pressures (``s1033`` of the robustness set): the pre-fit's trust
    region stops on SciPy's step tolerance at 2.2 times noise with the conductance 13 % off (a region
    shrunk in the penalty's valley; that tolerance is relative to the norm of all 167 variables).  The
    pre-fit starts a fresh region from there once (:data:`pneusim.fit.rules.PREFIT_RESTARTS`) and reaches
    the noise with all seven parameters within 1 % of the truth (measured: 0.986 times noise, 0.2 %)."""
    from pneusim.fit.stages import prefit
    from pneusim.fit.trust_region import trust_region

    spec = next(s for s in robustness_cases(48) if s.seed == 1033)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "pulses", "closed", False)
    rig, truth, rec = make_case(spec)
    setup = FitSetup(rec, rig, (), fit_free(True), None, None, None, 50)
    assert setup.prefit_start(2000) == 0
    pb, lo, hi = setup.problem(2000, 1e-6, 2)
    try:
        v0 = pb.join(setup.theta_start, initial_starts(pb, setup.theta_start, rec, 2000))
        defaults = [(name, i) for name, i in zip(setup.free, setup.index) if name in truth][:7]

        def largest_error(v):
            p = pb.params_of(pb.split(v)[0])
            return max(abs(p[i] / truth[name] - 1.0) for name, i in defaults)

        v_once, rms_once, once = trust_region(pb, v0, lo, hi)
        assert once["status"] == "step tolerance" and once["restarts"] == 0
        assert rms_once > ABOVE_NOISE_WARNING and largest_error(v_once) > 0.05
        v, rms, info = prefit(pb, v0, lo, hi)
        assert info["restarts"] >= 1, info
        assert rms <= ABOVE_NOISE_WARNING and largest_error(v) < 0.01
    finally:
        pb.close()


@pytest.mark.minutes
def test_fit_started_at_the_truth_of_a_chaotic_open_loop_recording_stays_at_noise():
    """Paper 2, open-loop multisine without pressures (``s1007`` of the robustness set), started at its eight
    true values.  The piston stick-slips from sample to sample, and at the truth the segments started from
    the chained simulation leave the recorded slip pattern within seconds (their own samples at 3-20 times
    noise from the ninth segment on).  The pre-fit without pressures takes the direct route only, and that
    stops at 1.55; the fit at 1.65 with the parameters off, where the Kalman filter's segment starts no
    longer help (1.65, then 1.81): a strict expected failure until stop 36.  The prediction-error route,
    from the same start, is kept and brings it to the noise (0.87, all seven truths within 0.25 sigma)."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1007)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "multisine", "open", False)
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True, start_values=truth)
    route = result.solver["prediction_error_route"]
    assert route is not None and route["kept"], (route, result.solver["tracked_route"])
    s = score(result, truth)
    assert result.converged_to_noise, (result.normalised_residuals, result.solver["prefit_attempts"])
    assert s["inside_3_sigma"] >= s["parameters"] - 1, s["z"]


def _window(seed: int, at_truth: bool = False):
    """``(problem of the 2000-sample pre-fit window, setup, truth)`` of robustness case ``seed``, the setup
    starting from the data sheet or from the truth."""
    spec = next(s for s in robustness_cases(48) if s.seed == seed)
    rig, truth, rec = make_case(spec)
    setup = FitSetup(rec, rig, (), fit_free(True), None, None, truth if at_truth else None, 50)
    pb, _, _ = setup.problem(2000, 1e-6, 1)
    return pb, setup, truth


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
    """``s1030`` fitted from the data sheet: the shooting fit ends far above noise (9.7 times it before this
    route existed), the prediction-error route is kept and the fit reaches the noise with every truth
    within 3 sigma."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1030)
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    route = result.solver["prediction_error_route"]
    assert route is not None and route["kept"], (route, result.solver["prefit_attempts"])
    assert min(a["rms_normalised"] for a in result.solver["prefit_attempts"]) > 5.0
    s = score(result, truth)
    assert result.converged_to_noise, result.normalised_residuals
    assert s["inside_3_sigma"] == s["parameters"], s["z"]


@pytest.mark.minutes
def test_chaotic_open_loop_fit_reaches_noise_through_tracked_starts():
    """Paper 2, open-loop steps without pressures (``s1027`` of the robustness set): every fit from the
    three starts ends above noise (the best at 1.63, the Stribeck velocity at 0.54 and the viscous friction
    at 0.64 of the truth, 3 of 7 truths within 3 sigma).  From segment starts tracked by the Kalman filter
    at that fit's parameters the continuation reaches the noise, kept, with every truth within 3 sigma."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1027)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "steps", "open", False)
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    tracked = result.solver["tracked_route"]
    assert tracked is not None and tracked["kept"], (tracked, result.solver["prefit_attempts"])
    assert min(a["fit_rms_normalised"] for a in result.solver["prefit_attempts"] if "fit_rms_normalised" in a) > 1.1
    s = score(result, truth)
    assert result.converged_to_noise, result.normalised_residuals
    assert s["inside_3_sigma"] == s["parameters"], s["z"]


@pytest.mark.minutes
def test_open_loop_stick_slip_with_pressures_takes_the_short_segment_route():
    """Paper 2, open-loop steps with both pressures (``s1026`` of the robustness set): the piston
    stick-slips from sample to sample through slow motion.  The 50-sample pre-fit ends above noise with the
    friction tens of percent off (the fit then at 2.11 times noise, 3 of 7 truths within 3 sigma); its
    route through 10-sample segments ends clearly lower on the same problem, is kept, and the fit reaches
    the noise with every truth within 3 sigma."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1026)
    assert (spec.rig_name, spec.kind, spec.loop, spec.pressures) == ("paper2-enfield", "steps", "open", True)
    rig, truth, rec = make_case(spec)
    result = fit_recording(rec, rig, free=fit_free(True), quiet=True)
    route = result.solver["prefit_attempts"][0]["short_segments"]
    assert route["kept"] and route["rms_normalised"] < result.solver["prefit_attempts"][0]["rms_normalised"]
    s = score(result, truth)
    assert result.converged_to_noise, (result.normalised_residuals, result.solver["prefit_attempts"])
    assert s["inside_3_sigma"] == s["parameters"], s["z"]


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
