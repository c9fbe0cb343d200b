"""Paper 2 scenario (shortened) through the command line: the numbers written in metrics.json are
recomputed independently from the written recordings and predictions."""

import numpy as np
import pytest
from scipy import signal as sps

from pneusim.recording import read_recording

from physical_checks import check_physical_fit_recovers_the_rig
from independent import arx_ls, read_predictions, rows_of, simulate_estimated_x0, stats

GAIN = 32.808          # paper2-enfield position sensor, V/m
N_EST = 1000           # 20 s at 10 ms, half for estimation
#: out of the quick tier: every test reads the paper 2 run of the session (the scenario, shortened to 20 s)
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def data(paper2_run):
    out, _ = paper2_run
    rec = read_recording(out / "recording.csv")
    return rec.position_m * GAIN - 5.0, rec.reference_m * GAIN - 5.0, rec


def test_writes_complete_report(paper2_run):
    out, m = paper2_run
    for name in ("report.md", "report.html", "metrics.json", "recording.csv", "predictions.csv",
                 "variant-literal-open-loop-reading.csv", "validation.png", "published-s.png"):
        assert (out / name).stat().st_size > 0, name
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") == len(m["files"]["figures"]) >= 4
    assert "src=\"http" not in html and "<link" not in html and "<script" not in html
    md = (out / "report.md").read_text()
    for text in ("paper fit %", "77.9", "75.43", "77.59", "86.64", "0.6 Hz term appears twice",
                 "How the input is applied", "Equation 4 under three time-unit readings", "Which reading the physics"):
        assert text in md, text
    assert m["n_samples"] == 2000 and m["n_estimation"] == N_EST


def test_input_is_equation_1_as_printed(data):
    _, u, rec = data
    t = rec.time_s
    np.testing.assert_allclose(u, 0.04 * np.cos(2 * np.pi * 0.6 * t) + 0.5 * np.cos(2 * np.pi * 0.08 * t)
                               + 0.9 * np.cos(2 * np.pi * 0.6 * t), atol=1e-9)


def test_every_row_recomputed_from_predictions(data, paper2_run):
    out, m = paper2_run
    y, u, _ = data
    pred = read_predictions(out / "predictions.csv")
    np.testing.assert_allclose(pred["y"], y, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(pred["u"], u, rtol=1e-9, atol=1e-12)
    scored = [r for r in m["rows"] if r["status"] == "ok" and r.get("fit_percent") is not None]
    assert {r["identifier"] for r in scored} >= {"published eq. 4"}
    for row in scored:
        yhat = pred[f"{row['identifier']} | {row['reading']}"]
        assert np.isnan(yhat[:N_EST]).all() and not np.isnan(yhat[N_EST:]).any()    # validation half only
        ref = stats(pred["y"], yhat)
        for key in ("n_scored", "fit_percent", "mse", "error_std", "actual_std", "predicted_max"):
            assert row[key] == pytest.approx(ref[key], rel=1e-6, abs=1e-10), (row["identifier"], row["reading"], key)


def test_blackbox_outputs_are_simulations_of_their_models(data, paper2_run):
    """Each model's written output is its transfer function simulated on the validation input from the
    least-squares initial state; the ARX polynomials themselves are recomputed by least squares."""
    out, m = paper2_run
    y, u, _ = data
    pred = read_predictions(out / "predictions.csv")
    checked = 0
    for row in m["rows"]:
        if row["kind"] not in ("arx", "armax", "ss", "tf") or row["status"] != "ok" or "model_num" not in row:
            continue
        yhat = simulate_estimated_x0(np.array(row["model_num"]), np.array(row["model_den"]), u[N_EST:], y[N_EST:])
        written = pred[f"{row['identifier']} | {row['reading']}"][N_EST:]
        np.testing.assert_allclose(written, yhat, rtol=0, atol=1e-6 * np.ptp(y), err_msg=row["identifier"])
        checked += 1
    arx = rows_of(m, "ARX")[0]
    if arx["status"] == "ok":
        A, B = arx_ls(y[:N_EST], u[:N_EST], 3, 3, 1)
        np.testing.assert_allclose(arx["model_den"], A, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(arx["model_num"], B, rtol=1e-6, atol=1e-9)
        assert arx["fit_percent"] <= 100.0
    assert checked >= 1 or all(rows_of(m, n)[0]["status"] != "ok" for n in ("ARX", "ARMAX", "State Space"))


def test_eq4_readings_recomputed(data, paper2_run):
    out, m = paper2_run
    y, u, _ = data
    yv, uv = y[N_EST:], u[N_EST:]
    rows = {r["reading"]: r for r in rows_of(m, "published eq. 4")}
    assert set(rows) == {"time unit = s", "time unit = ms", "time unit = sample"}
    phase = {}
    for reading, T in (("time unit = s", 1.0), ("time unit = ms", 1e-3), ("time unit = sample", 0.01)):
        num = np.array([0.01284 * T ** 2, -0.000123 * T, 1.91e-6])
        den = np.array([T ** 3, 0.002305 * T ** 2, 0.0001027 * T, 2.297e-7])
        assert rows[reading]["delay_s"] == pytest.approx(15 * T)
        _, h = sps.freqs(num, den, worN=2 * np.pi * np.array([0.08, 0.6]))
        phase[reading] = np.degrees(np.angle(h))
        np.testing.assert_allclose([b["phase_deg"] for b in rows[reading]["band"]], phase[reading], atol=1e-6)
        nd = int(round(15 * T / 0.01))
        if nd >= len(uv):
            continue
        sysd = sps.StateSpace(*sps.tf2ss(num, den)).to_discrete(0.01)
        _, yhat, _ = sps.dlsim(sysd, np.concatenate((np.zeros(nd), uv))[:len(uv)])
        assert rows[reading]["fit_percent"] == pytest.approx(stats(yv, yhat.ravel())["fit_percent"], rel=1e-6,
                                                             abs=1e-6)
    assert rows["time unit = ms"]["dc_gain"] == pytest.approx(1.91e-6 / 2.297e-7)
    # the classification follows the phase at the lowest excitation frequency, recomputed above
    for reading, ph in phase.items():
        beh = rows[reading]["behaviour"]
        assert ("integrator" in beh) == (abs(ph[0] + 90) <= 30) and ("type 0" in beh) == (abs(ph[0]) <= 30)
    assert "dead time" in rows["time unit = s"]["behaviour"]          # 15 s of a 20 s record
    md = (out / "report.md").read_text()
    assert "The physics supports the reading in samples of 10 ms" in md
    assert "a valve-driven cylinder is an integrator" in md and "type 0" in md


def test_literal_reading_hits_end_stop(paper2_run):
    out, m = paper2_run
    var = m["variants"][0]
    rec = read_recording(out / "variant-literal-open-loop-reading.csv")
    stroke = 0.3048
    at = (rec.position_m <= 1e-3) | (rec.position_m >= stroke - 1e-3)
    assert var["fraction_at_end_stop"] == pytest.approx(at.mean())
    assert var["first_end_stop_s"] == pytest.approx(np.argmax(at) * 0.01) and var["first_end_stop_s"] < 5.0
    # the rig integrates its valve command: velocity against command from the null, away from the stops
    x, du = rec.position_m, rec.valve_cmd_V - 5.0
    v = np.gradient(x, 0.01)
    ok = (x > 5e-3) & (x < stroke - 5e-3)
    ok[:50] = False
    k = np.sum(v[ok] * du[ok]) / np.sum(du[ok] ** 2)
    assert var["valve_velocity_gain"]["gain_m_per_s_per_V"] == pytest.approx(k, rel=1e-9)
    # the chosen closed-loop reading keeps the piston inside the stroke
    main_rec = read_recording(out / "recording.csv")
    assert 0.01 < main_rec.position_m.min() and main_rec.position_m.max() < stroke - 0.01


def test_physical_fit_row_recovers_the_rig(paper2_run):
    check_physical_fit_recovers_the_rig(paper2_run[1])
