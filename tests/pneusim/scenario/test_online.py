"""The paper 1 RLS (eq. 8): converges, predicts h steps correctly, and runs inside the loop."""

import numpy as np
import pytest

from pneusim.scenario import online
from pneusim.scenario.online import PaperRLS


def _arx_data(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    a, b = [-1.5, 0.7], [0.5, 0.2]          # y(k) = 1.5 y(k-1) - 0.7 y(k-2) + 0.5 u(k-1) + 0.2 u(k-2)
    u = rng.standard_normal(n)
    y = np.zeros(n)
    for k in range(2, n):
        y[k] = -a[0] * y[k - 1] - a[1] * y[k - 2] + b[0] * u[k - 1] + b[1] * u[k - 2]
    return y, u, np.array(a + b)


def test_rls_converges_to_true_theta():
    y, u, theta = _arx_data()
    est = PaperRLS(2, forgetting=1.0, initial_covariance=1000.0, horizons=(1,))
    for k in range(len(y)):
        est.update(y[k])
        est.add_input(u[k])
    np.testing.assert_allclose(est.theta, theta, atol=1e-4)  # P(0) = c I is a weak prior


def test_h_step_prediction_matches_direct_iteration():
    y, u, theta = _arx_data(400, seed=1)
    est = PaperRLS(2, forgetting=0.99, initial_covariance=100.0, horizons=(1, 3, 7))
    thetas, preds = [], []
    for k in range(len(y)):
        preds.append(est.update(y[k]))
        thetas.append(est.theta.copy())
        est.add_input(u[k])
    for k in (50, 200, 399):
        for h in (1, 3, 7):
            a, b = thetas[k - h][:2], thetas[k - h][2:]
            hist = list(y[:k - h + 1])
            for j in range(k - h + 1, k + 1):
                hist.append(-a[0] * hist[j - 1] - a[1] * hist[j - 2] + b[0] * u[j - 1] + b[1] * u[j - 2])
            assert preds[k][h] == pytest.approx(hist[k], rel=1e-9, abs=1e-12)


def test_rls_runs_inside_the_loop(monkeypatch):
    """Each update happens between two plant steps: measure, update, control, step."""
    from pneusim.experiment import Experiment, default_controller
    from pneusim.rig import load_rig

    events = []
    orig_update, orig_step = PaperRLS.update, online.SimulatedPlant.step
    monkeypatch.setattr(PaperRLS, "update", lambda self, y: (events.append("u"), orig_update(self, y))[1])
    monkeypatch.setattr(online.SimulatedPlant, "step", lambda self, c: (events.append("s"), orig_step(self, c))[1])
    rig = load_rig("paper1-mre")
    n = 60
    exp = Experiment("closed", 0.001, np.full(n, 0.03), default_controller(rig), warmup_s=0.0)
    res = online.simulate_online(rig, exp, {"r": PaperRLS(2)}, lambda p: p * 100, lambda c, k: c)
    assert "".join(events) == "us" * (n - 1) + "u"
    assert res.predictions[("r", 1)].shape == (n,)


def test_sysid_engine_matches_paper_rls():
    sysid = pytest.importorskip("sysid")
    if not hasattr(sysid, "RecursiveARX"):
        pytest.skip("sysid.RecursiveARX not available")
    y, u, _ = _arx_data(600, seed=4)
    y = y + 0.01 * np.random.default_rng(5).standard_normal(len(y))
    ests = [online.PaperRLS(3, 0.98, 500.0, (1, 4)), online.SysidRLS(3, 0.98, 500.0, (1, 4))]
    out = [[], []]
    for k in range(len(y)):
        for e, o in zip(ests, out):
            o.append(e.update(y[k]))
            e.add_input(u[k])
    for h in (1, 4):
        a = np.array([p[h] for p in out[0]])
        b = np.array([p[h] for p in out[1]])
        np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(ests[0].theta, ests[1].theta, rtol=1e-7, atol=1e-10)
