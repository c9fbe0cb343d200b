"""Paper 1 scenario (shortened) through the real runner: the numbers written in metrics.json are
recomputed independently from the written recording and predictions."""

from pathlib import Path

import numpy as np
import pytest

from pneusim.recording import read_recording
from pneusim.scenario.schema import load_scenario

from physical_checks import check_physical_fit_recovers_the_rig
from independent import h_step, read_predictions, rows_of, rls_history, stats

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
#: out of the quick tier: every test reads the paper 1 run of the session (the scenario, shortened to 4 s)
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def data(paper1_run):
    out, _ = paper1_run
    rec = read_recording(out / "recording.csv")
    return rec.position_m * 100.0, rec.valve_cmd_V, rec          # cm and V, the scenario's data units


def test_writes_complete_report(paper1_run):
    out, m = paper1_run
    for name in ("report.md", "report.html", "metrics.json", "recording.csv", "predictions.csv", "recording.png",
                 "rls-rls-arma-order-4-h10.png", "published-z.png"):
        assert (out / name).stat().st_size > 0, name
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") == len(m["files"]["figures"]) >= 7
    assert "src=\"http" not in html and "<link" not in html and "<script" not in html    # self-contained
    md = (out / "report.md").read_text()
    for text in ("Table 1 layout", "square error (cm^2)", "paper square error", "Effect of step prediction",
                 "published eq. 10 (4th order)", "free-run fit %", "naive: yhat(k) = y(k-1)"):
        assert text in md, text
    assert m["n_samples"] == 4000 and m["sample_time_s"] == 0.001 and m["overrides"] == ["experiment.duration_s=4.0"]


def test_the_rls_ran_inside_the_closed_loop(data, paper1_run):
    _, m = paper1_run
    y, u, rec = data
    assert rec.loop == "closed" and rec.metadata.get("controller") == "proportional"
    # the valve command is the proportional law on the measured position: the loop was closed sample by sample
    kp, u0 = float(rec.metadata["kp_V_per_m"]), float(rec.metadata["u0_V"])
    np.testing.assert_allclose(u, np.clip(u0 + kp * (rec.reference_m - rec.position_m), 0.0, 10.0), atol=1e-6)
    rows = [r for r in m["rows"] if r["kind"] == "rls"]
    assert rows and all(r["reading"].startswith("online") for r in rows)


def test_table1_recomputed_from_recording(data, paper1_run):
    _, m = paper1_run
    y, u, _ = data
    spec = load_scenario(SCENARIOS / "paper1-online-rls.toml")
    for ident in (i for i in spec["identifiers"] if i["kind"] == "rls"):
        n = ident["order"]
        thetas = rls_history(y, u, n, ident["forgetting"], ident["initial_covariance"])
        for h in ident["horizons"]:
            row = next(r for r in rows_of(m, ident["name"]) if r["horizon"] == h)
            ref = stats(y, h_step(y, u, thetas, n, h))
            for key in ("n_scored", "square_error", "error_std", "fit_percent", "actual_min", "actual_max",
                        "actual_std", "predicted_min", "predicted_max", "predicted_std", "error_min", "error_max"):
                assert row[key] == pytest.approx(ref[key], rel=1e-5, abs=1e-9), (ident["name"], h, key)
        np.testing.assert_allclose(rows_of(m, ident["name"])[0]["theta_final"], thetas[-1], rtol=1e-5, atol=1e-9)
    # the 4th-order model is scored at 1, 5 and 10 steps, and gets worse with the horizon
    h = {r["horizon"]: r["square_error"] for r in rows_of(m, "RLS ARMA order 4")}
    assert sorted(h) == [1, 5, 10] and h[1] < h[5] < h[10]


def test_every_row_recomputed_from_predictions(data, paper1_run):
    out, m = paper1_run
    y, _, _ = data
    pred = read_predictions(out / "predictions.csv")
    np.testing.assert_allclose(pred["y"], y, rtol=1e-9, atol=1e-12)
    scored = [r for r in m["rows"] if r["status"] == "ok"]
    assert len(scored) >= 17
    for row in scored:
        ref = stats(pred["y"], pred[f"{row['identifier']} | {row['reading']}"])
        for key in ("n_scored", "square_error", "error_std", "fit_percent", "predicted_min", "error_max"):
            assert row[key] == pytest.approx(ref[key], rel=1e-6, abs=1e-10), (row["identifier"], row["reading"], key)


def test_published_eq10_recomputed(data, paper1_run):
    _, m = paper1_run
    y, u, _ = data
    ident = next(i for i in load_scenario(SCENARIOS / "paper1-online-rls.toml")["identifiers"]
                 if i["name"].startswith("published eq. 10"))
    num, den = np.array(ident["num"]), np.array(ident["den"])
    n = len(den) - 1
    for offset, reading in ((0.0, "as printed"), (5.0, "as printed, u - 5")):
        # the regression written out: yhat(k) = -a1 y(k-1) - ... - an y(k-n) + b0 u(k) + ... + bn u(k-n)
        e = [y[k] - (-den[1:] @ y[k - n:k][::-1] + num @ (u[k - n:k + 1][::-1] - offset)) for k in range(n, len(y))]
        row = next(r for r in rows_of(m, ident["name"]) if r["reading"] == reading)
        assert row["square_error"] == pytest.approx(np.mean(np.square(e)), rel=1e-6)
        assert row["n_scored"] == len(e)
        # free run: y(0) + G(z) (u - u(0)), by the difference equation
        free = np.zeros(len(y))
        du = u - u[0]
        for k in range(len(y)):
            free[k] = (sum(num[i] * du[k - i] for i in range(n + 1) if k - i >= 0)
                       - sum(den[i] * free[k - i] for i in range(1, n + 1) if k - i >= 0))
        ref = stats(y, y[0] + free)
        assert row["free_run_fit_percent"] == pytest.approx(ref["fit_percent"], rel=1e-6)
        assert row["dc_gain"] == pytest.approx(num.sum() / den.sum(), rel=1e-9)


def test_physical_fit_row_recovers_the_rig(paper1_run):
    check_physical_fit_recovers_the_rig(paper1_run[1])
