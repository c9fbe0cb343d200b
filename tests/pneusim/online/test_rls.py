"""The compiled RLS of the real-time loop against eq. 8 written in numpy, and the real-time OS settings."""

import os

import numpy as np
import pytest

from pneusim.scenario.online import PaperRLS


def _dot(x, y):
    acc = 0.0
    for a, b in zip(x, y):
        acc += a * b
    return acc


def _reference_rls(y, u, n, lam, c, horizons, blas=False):
    """Paper 1's eq. 8 and the h-step predictions, written independently of the kernel: in plain
    Python floats summing left to right (``blas=False``), or with numpy's BLAS products (``blas=True``)."""
    m = 2 * n
    theta, P = [0.0] * m, [[c if i == j else 0.0 for j in range(m)] for i in range(m)]
    thetas, preds = np.empty((len(y), m)), {h: np.full(len(y), np.nan) for h in horizons}
    y, u = [float(v) for v in y], [float(v) for v in u]
    past = lambda s, k, i: s[k - i] if k - i >= 0 else 0.0        # zeros before the first sample
    for k in range(len(y)):
        for h in horizons:
            if k >= n + h:
                a, b = thetas[k - h][:n].tolist(), thetas[k - h][n:].tolist()
                hist = {j: y[j] for j in range(k - h - n + 1, k - h + 1)}
                for j in range(k - h + 1, k + 1):
                    acc = 0.0
                    for i in range(n):
                        acc += b[i] * u[j - 1 - i] - a[i] * hist[j - 1 - i]
                    hist[j] = acc
                preds[h][k] = hist[k]
        psi = [-past(y, k, i) for i in range(1, n + 1)] + [past(u, k, i) for i in range(1, n + 1)]
        if blas:
            Pa, psia, tha = np.array(P), np.array(psi), np.array(theta)
            Ppsi = Pa @ psia
            denom = lam + psia @ Ppsi
            theta = (tha + Ppsi * ((y[k] - psia @ tha) / denom)).tolist()
            P = ((Pa - np.outer(Ppsi, Ppsi) / denom) / lam).tolist()
        else:
            Ppsi = [_dot(row, psi) for row in P]
            denom = lam + _dot(psi, Ppsi)
            e = (y[k] - _dot(psi, theta)) / denom
            theta = [theta[i] + Ppsi[i] * e for i in range(m)]
            P = [[(P[i][j] - Ppsi[i] * Ppsi[j] / denom) / lam for j in range(m)] for i in range(m)]
        thetas[k] = theta
    return thetas, preds, np.array(P)


@pytest.fixture(scope="module")
def loop_data():
    """Output (cm) and command (V) of the paper-1 loop from the simulator: what the estimators see live."""
    from pneusim.mre.run import run_mre
    from pneusim.mre.scenario import validate_mre
    import tempfile

    spec = validate_mre({
        "mre": {"name": "t", "duration_s": 2.0, "warmup_s": 0.05, "seed": 4},
        "rig": {"name": "paper1-mre"},
        "controller": {"kind": "proportional", "kp_V_per_m": 40.0},
        "reference": {"kind": "pulses", "unit": "m", "base": 0.005, "amplitude": [0.01, 0.04],
                      "width_s": [0.1, 0.4], "rest_s": [0.2, 0.5], "sign": "positive"},
    }, "t.toml")
    with tempfile.TemporaryDirectory() as tmp:
        res = run_mre(spec, tmp, mode="fast", report=False).result
    return res.position_m * 100.0, res.valve_cmd_V


@pytest.mark.parametrize("order", [3, 4, 5])
def test_compiled_rls_equals_eq8_in_numpy_over_a_loop_recording(loop_data, order):
    y, u = loop_data
    horizons = (1, 5, 10)
    est = PaperRLS(order, 0.99, 1000.0, horizons)
    thetas, preds = np.empty((len(y), 2 * order)), {h: np.empty(len(y)) for h in horizons}
    for k in range(len(y)):
        for h, v in est.update(y[k]).items():
            preds[h][k] = v
        est.add_input(u[k])
        thetas[k] = est.theta
    # the same arithmetic in the same order: the same doubles
    ref_thetas, ref_preds, ref_P = _reference_rls(y, u, order, 0.99, 1000.0, horizons)
    assert est.k == len(y) == 2000
    np.testing.assert_array_equal(thetas, ref_thetas)
    np.testing.assert_array_equal(est.P, ref_P)
    for h in horizons:
        assert np.isnan(preds[h][:order + h]).all() and np.isfinite(preds[h][order + h:]).all()
        np.testing.assert_array_equal(preds[h], ref_preds[h])
    # numpy's BLAS sums in another order; RLS on this loop's data turns a one-ulp change of the data
    # into ~1e-10 of theta, so the kernel must sit within that spread of the BLAS result, no further
    blas, _, _ = _reference_rls(y, u, order, 0.99, 1000.0, (1,), blas=True)
    blas_ulp, _, _ = _reference_rls(np.nextafter(y, np.inf), u, order, 0.99, 1000.0, (1,), blas=True)
    scale = np.abs(blas).max(axis=0)
    spread = (np.abs(blas_ulp - blas).max(axis=0) / scale).max()
    assert 1e-13 < spread < 1e-8
    assert (np.abs(thetas - blas).max(axis=0) / scale).max() < 10 * spread


def test_theta_logger_writes_the_rows_the_loop_keeps():
    est = PaperRLS(2, 0.98, 100.0, (1,))
    log = np.full((3, 4), np.nan)
    write = est.theta_logger(log)
    for k, (yk, uk) in enumerate([(0.1, 1.0), (0.3, -1.0), (0.2, 0.5)]):
        est.update(yk)
        est.add_input(uk)
        write(k)
        np.testing.assert_array_equal(log[k], est.theta)
    with pytest.raises(IndexError):
        write(3)


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="Linux scheduling calls")
def test_realtime_settings_are_restored_or_refused_with_one_line(monkeypatch):
    from pneusim.mre.rt import RealtimeScope, RealtimeSettings

    before = (os.sched_getscheduler(0), os.sched_getparam(0), os.sched_getaffinity(0))
    with RealtimeScope(RealtimeSettings(priority=10, cpu=min(os.sched_getaffinity(0)))) as scope:
        if "SCHED_FIFO 10" in scope.applied:
            assert os.sched_getscheduler(0) == os.SCHED_FIFO
        else:                                   # not permitted here: said so in one line
            assert any("SCHED_FIFO" in n for n in scope.notices)
    assert (os.sched_getscheduler(0), os.sched_getparam(0), os.sched_getaffinity(0)) == before

    def refuse(*a):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    with RealtimeScope(RealtimeSettings(priority=10, lock_memory=False, timer_slack=False)) as scope:
        pass
    assert scope.applied == [] and scope.describe() == "normal scheduling"
    assert scope.notices == ["mre: SCHED_FIFO priority 10 not available (Operation not permitted); "
                             "normal scheduling: expect more lateness under load"]


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="Linux scheduling calls")
def test_cli_realtime_run_says_what_it_got_and_gives_the_scheduler_back(tmp_path, capsys):
    from pneusim.cli import main

    mre = tmp_path / "m.toml"
    # overruns allowed: this test is about the scheduler settings, not timing (a loaded machine overruns)
    mre.write_text('[mre]\nname = "t"\nduration_s = 0.1\nwarmup_s = 0.0\noverrun_budget = 1.0\n'
                   '[rig]\nname = "paper1-mre"\n'
                   '[controller]\nkind = "proportional"\nkp_V_per_m = 40.0\n[reference]\nkind = "steps"\n'
                   'unit = "m"\nlow = 0.02\nhigh = 0.05\nhold_s = [0.02, 0.04]\n', encoding="utf-8")
    before = (os.sched_getscheduler(0), os.sched_getparam(0))
    assert main(["mre", str(mre), "--realtime", "--rt-priority", "10", "--no-report", "--out", str(tmp_path / "o")]) == 0
    out, err = capsys.readouterr()
    assert (os.sched_getscheduler(0), os.sched_getparam(0)) == before
    line = next(x for x in out.splitlines() if x.startswith("real-time settings: "))
    assert "SCHED_FIFO 10" in line or ("normal scheduling" in line and "SCHED_FIFO priority 10 not available" in err)
    import json
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["realtime_os"]["applied"] == line[len("real-time settings: "):]
