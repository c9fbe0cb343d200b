"""The paper 1 RLS (eq. 8): converges, predicts h steps correctly, and its compiled kernel gives the doubles
of eq. 8 written in plain Python over a recording of the loop; the sysid engine agrees."""

import tempfile

import numpy as np
import pytest

from pneusim.mre.run import run_mre
from pneusim.mre.scenario import validate_mre
from pneusim.online import PaperRLS, SysidRLS


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


def test_sysid_engine_matches_paper_rls():
    sysid = pytest.importorskip("sysid")
    if not hasattr(sysid, "RecursiveARX"):
        pytest.skip("sysid.RecursiveARX not available")
    y, u, _ = _arx_data(600, seed=4)
    y = y + 0.01 * np.random.default_rng(5).standard_normal(len(y))
    ests = [PaperRLS(3, 0.98, 500.0, (1, 4)), SysidRLS(3, 0.98, 500.0, (1, 4))]
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
