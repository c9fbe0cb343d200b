"""Both paper scenarios run through the real runner (reduced duration); the numbers in the written
metrics.json are recomputed independently from the written recordings."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy import signal as sps

from pneusim.cli import main
from pneusim.recording import read_recording
from pneusim.scenario.schema import load_scenario


def _rows(metrics, identifier):
    return [r for r in metrics["rows"] if r["identifier"] == identifier]


def _rls_one_step(y, u, n, lam, c):
    """Textbook RLS (Ljung form, gain vector), written apart from pneusim's."""
    theta, P = np.zeros(2 * n), c * np.eye(2 * n)
    yhat = np.full(len(y), np.nan)
    for k in range(len(y)):
        phi = np.array([-(y[k - j] if k - j >= 0 else 0.0) for j in range(1, n + 1)]
                       + [(u[k - j] if k - j >= 0 else 0.0) for j in range(1, n + 1)])
        if k >= n + 1:
            yhat[k] = phi @ theta
        gain = P @ phi / (lam + phi @ P @ phi)
        theta = theta + gain * (y[k] - phi @ theta)
        P = (P - np.outer(gain, phi @ P)) / lam
    return yhat


@pytest.fixture(scope="module")
def paper1(tmp_path_factory, scenarios_dir_module):
    out = tmp_path_factory.mktemp("paper1")
    rc = main(["run", str(scenarios_dir_module / "paper1-online-rls.toml"), "--out", str(out),
               "--set", "experiment.duration_s=4.0", "--no-progress"])
    assert rc == 0
    return out, json.loads((out / "metrics.json").read_text())


@pytest.fixture(scope="module")
def scenarios_dir_module():
    from pathlib import Path
    return Path(__file__).resolve().parents[2] / "scenarios"


def test_paper1_writes_complete_report(paper1):
    out, m = paper1
    for name in ("report.md", "report.html", "metrics.json", "recording.csv", "recording.png",
                 "rls-rls-arma-order-4-h10.png"):
        assert (out / name).stat().st_size > 0, name
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") == len(m["files"]["figures"]) >= 6
    md = (out / "report.md").read_text()
    assert "Table 1 layout" in md and "paper square error" in md and "Effect of step prediction" in md
    assert m["n_samples"] == 4000 and m["sample_time_s"] == 0.001


def test_paper1_table1_recomputed_from_recording(paper1, scenarios_dir_module):
    out, m = paper1
    spec = load_scenario(scenarios_dir_module / "paper1-online-rls.toml")
    rec = read_recording(out / "recording.csv")
    assert rec.loop == "closed"
    y, u = rec.position_m * 100.0, rec.valve_cmd_V          # cm and V, the scenario's data units
    for ident in (i for i in spec["identifiers"] if i["kind"] == "rls"):
        row = next(r for r in _rows(m, ident["name"]) if r["horizon"] == 1)
        yhat = _rls_one_step(y, u, ident["order"], ident["forgetting"], ident["initial_covariance"])
        ok = np.isfinite(yhat)
        e = y[ok] - yhat[ok]
        assert row["n_scored"] == ok.sum()
        assert row["square_error"] == pytest.approx(np.mean(e ** 2), rel=1e-6)
        assert row["error_std"] == pytest.approx(np.std(e), rel=1e-6)
        assert row["actual_max"] == pytest.approx(y[ok].max(), rel=1e-12)
        assert row["predicted_min"] == pytest.approx(yhat[ok].min(), rel=1e-6, abs=1e-9)
    # the 4th-order model is also scored at 1, 5 and 10 steps, and gets worse with the horizon
    h = {r["horizon"]: r["square_error"] for r in _rows(m, "RLS ARMA order 4")}
    assert sorted(h) == [1, 5, 10] and h[1] < h[5] < h[10]


def test_paper1_published_eq10_recomputed(paper1, scenarios_dir_module):
    out, m = paper1
    spec = load_scenario(scenarios_dir_module / "paper1-online-rls.toml")
    ident = next(i for i in spec["identifiers"] if i["name"].startswith("published eq. 10"))
    rec = read_recording(out / "recording.csv")
    y, u = rec.position_m * 100.0, rec.valve_cmd_V
    num, den = np.array(ident["num"]), np.array(ident["den"])
    n = len(den) - 1
    for offset, reading in ((0.0, "as printed"), (5.0, "as printed, u - 5")):
        # the regression written out: yhat(k) = -a1 y(k-1) - ... - an y(k-n) + b0 u(k) + ... + bn u(k-n)
        e = [y[k] - (-den[1:] @ y[k - n:k][::-1] + num @ (u[k - n:k + 1][::-1] - offset)) for k in range(n, len(y))]
        row = next(r for r in _rows(m, ident["name"]) if r["reading"] == reading)
        assert row["square_error"] == pytest.approx(np.mean(np.square(e)), rel=1e-6)
        assert row["n_scored"] == len(e)


def test_paper1_physical_fit_row_is_present(paper1):
    _, m = paper1
    row = _rows(m, "fitted physical model")[0]
    assert row["status"] in ("ok", "not available", "failed")
    if row["status"] != "ok":
        assert row["reason"]


@pytest.fixture(scope="module")
def paper2(tmp_path_factory, scenarios_dir_module):
    out = tmp_path_factory.mktemp("paper2")
    proc = subprocess.run([sys.executable, "-m", "pneusim.cli", "run",
                           str(scenarios_dir_module / "paper2-multisine.toml"), "--out", str(out),
                           "--set", "experiment.duration_s=20.0", "--no-progress"],
                          capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    return out, json.loads((out / "metrics.json").read_text())


def test_paper2_writes_complete_report(paper2):
    out, m = paper2
    for name in ("report.md", "report.html", "metrics.json", "recording.csv",
                 "variant-literal-open-loop-reading.csv", "validation.png", "published-s.png"):
        assert (out / name).stat().st_size > 0, name
    md = (out / "report.md").read_text()
    assert "paper fit %" in md and "77.9" in md and "86.64" in md and "0.6 Hz term appears twice" in md
    assert m["n_samples"] == 2000 and m["n_estimation"] == 1000


def test_paper2_eq4_readings_recomputed(paper2):
    out, m = paper2
    rec = read_recording(out / "recording.csv")
    gain = 32.808
    y = rec.position_m * gain - 5.0
    u = rec.reference_m * gain - 5.0                      # the multisine as printed, in volts
    t = rec.time_s
    np.testing.assert_allclose(u, 0.94 * np.cos(2 * np.pi * 0.6 * t) + 0.5 * np.cos(2 * np.pi * 0.08 * t),
                               atol=1e-9)
    yv, uv = y[1000:], u[1000:]
    rows = {r["reading"]: r for r in _rows(m, "published eq. 4")}
    assert set(rows) == {"time unit = s", "time unit = ms", "time unit = sample"}
    for reading, T in (("time unit = ms", 1e-3), ("time unit = sample", 0.01)):
        num = np.array([0.01284 * T ** 2, -0.000123 * T, 1.91e-6])
        den = np.array([T ** 3, 0.002305 * T ** 2, 0.0001027 * T, 2.297e-7])
        sysd = sps.StateSpace(*sps.tf2ss(num, den)).to_discrete(0.01)
        nd = int(round(15 * T / 0.01))
        _, yhat, _ = sps.dlsim(sysd, np.concatenate((np.zeros(nd), uv))[:len(uv)])
        yhat = yhat.ravel()
        fit = 100 * (1 - np.linalg.norm(yv - yhat) / np.linalg.norm(yv - yv.mean()))
        assert rows[reading]["fit_percent"] == pytest.approx(fit, rel=1e-6, abs=1e-6)
        assert rows[reading]["delay_s"] == pytest.approx(15 * T)
    assert rows["time unit = s"]["delay_s"] == 15.0
    assert rows["time unit = ms"]["dc_gain"] == pytest.approx(1.91e-6 / 2.297e-7)


def test_paper2_blackbox_rows_consistent(paper2):
    out, m = paper2
    for name in ("ARX", "ARMAX", "State Space", "General Transfer Function"):
        row = _rows(m, name)[0]
        assert row["status"] in ("ok", "not available", "failed")
        if row["status"] == "ok":
            assert row["fit_percent"] is not None and row["fit_percent"] <= 100
    arx = _rows(m, "ARX")[0]
    if arx["status"] == "ok":
        sysid = pytest.importorskip("sysid")
        rec = read_recording(out / "recording.csv")
        y, u = rec.position_m * 32.808 - 5.0, rec.reference_m * 32.808 - 5.0
        est, val = sysid.iddata(y[:1000], u[:1000], 0.01), sysid.iddata(y[1000:], u[1000:], 0.01)
        model = sysid.arx(est, [3, 3, 1])
        yhat = np.asarray(sysid.simulate(model, val, initial="estimate")).ravel()
        fit = 100 * (1 - np.linalg.norm(y[1000:] - yhat) / np.linalg.norm(y[1000:] - y[1000:].mean()))
        assert arx["fit_percent"] == pytest.approx(fit, rel=1e-6)


def test_paper2_literal_reading_hits_end_stop(paper2):
    out, m = paper2
    var = m["variants"][0]
    rec = read_recording(out / "variant-literal-open-loop-reading.csv")
    stroke = 0.3048
    at = (rec.position_m <= 1e-3) | (rec.position_m >= stroke - 1e-3)
    assert var["fraction_at_end_stop"] == pytest.approx(at.mean())
    assert var["first_end_stop_s"] is not None and var["first_end_stop_s"] < 5.0
    assert math.isclose(var["first_end_stop_s"], np.argmax(at) * 0.01)
    # the chosen closed-loop reading keeps the piston inside the stroke
    main_rec = read_recording(out / "recording.csv")
    assert 0.01 < main_rec.position_m.min() and main_rec.position_m.max() < stroke - 0.01
