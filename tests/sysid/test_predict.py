import math

import numpy as np
import pytest
from scipy.signal import lfilter

import sysid

from sysid_helpers import simulate_poly


def test_one_step_prediction_of_armax_matches_direct_formula():
    A, B, C = [1, -1.5, 0.7], [0, 1, 0.5], [1, -0.5, 0.2]
    d = simulate_poly(A, B, C=C, N=300, sigma=0.2, seed=1)
    m = sysid.idpoly(A, B, C=C)
    # C yhat = B u + (C - A) y
    direct = lfilter(B, C, d.u) + lfilter(np.subtract(C, A), C, d.y)
    np.testing.assert_allclose(sysid.predict(m, d, 1), direct, atol=1e-12)


def test_k_step_prediction_uses_only_old_outputs():
    d = simulate_poly([1, -1.5, 0.7], [0, 1, 0.5], C=[1, 0.3], N=200, sigma=0.2, seed=2)
    m = sysid.idpoly([1, -1.5, 0.7], [0, 1, 0.5], C=[1, 0.3])
    y2 = d.y.copy()
    y2[150:] += 10.0  # changing y(t) for t >= 150 must not change yhat(t|t-3) for t < 153
    d2 = sysid.iddata(y2, d.u, d.Ts)
    p1, p2 = sysid.predict(m, d, 3), sysid.predict(m, d2, 3)
    np.testing.assert_allclose(p1[:153], p2[:153], atol=1e-9)
    assert abs(p1[153] - p2[153]) > 1e-3


def test_large_k_tends_to_simulation_and_inf_is_simulation():
    d = simulate_poly([1, -0.8], [0, 1], C=[1, 0.5], N=300, sigma=0.1, seed=3)
    m = sysid.idpoly([1, -0.8], [0, 1], C=[1, 0.5])
    np.testing.assert_allclose(sysid.predict(m, d, math.inf), sysid.simulate(m, d))
    np.testing.assert_allclose(sysid.predict(m, d, 200)[250:], sysid.simulate(m, d)[250:], atol=1e-6)


def test_compare_fit_is_matlab_nrmse():
    d = simulate_poly([1, -0.8], [0, 1], N=300, sigma=0.0, seed=4)
    m = sysid.idpoly([1, -0.8], [0, 1])
    assert sysid.compare(d, m) == pytest.approx(100.0)
    m2 = sysid.idpoly([1, -0.8], [0, 0.5])
    expected = 100 * (1 - np.linalg.norm(d.y - 0.5 * d.y) / np.linalg.norm(d.y - d.y.mean()))
    assert sysid.compare(d, m2, initial="zero") == pytest.approx(expected)
    assert sysid.compare(d, m2) > sysid.compare(d, m2, initial="zero")  # default: estimated initial state


def test_estimated_initial_condition_removes_transient():
    d0 = simulate_poly([1, -0.95], [0, 1], N=400, sigma=0.0, seed=5)
    y = d0.y + 5.0 * 0.95 ** np.arange(1, 401)  # free response of a nonzero initial state
    d = sysid.iddata(y, d0.u, 1.0)
    m = sysid.idpoly([1, -0.95], [0, 1])
    assert sysid.compare(d, m, initial="estimate") == pytest.approx(100.0, abs=1e-6)
    assert sysid.compare(d, m) == pytest.approx(100.0, abs=1e-6)  # MATLAB's default: 'e'
    assert sysid.compare(d, m, initial="zero") < 99.0


# ------------------------------------------------------------------ horizons
def test_horizon_beyond_the_data_is_the_simulation_without_allocating_it():
    """The k impulse-response terms of the predictor would take 7.45 GiB for k = 10**9."""
    import tracemalloc
    d = simulate_poly([1, -1.5, 0.7], [0, 1, 0.5], C=[1, 0.3], N=300, sigma=0.1, seed=6)
    m = sysid.armax(d, [2, 2, 1, 1])
    sim = sysid.simulate(m, d)
    tracemalloc.start()
    try:
        for k in (300, 10**6, 10**9, 1e20):
            np.testing.assert_array_equal(sysid.predict(m, d, k), sim)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1e6, peak                                   # bytes: a few arrays of 300 samples
    assert sysid.compare(d, m, k=10**9) == sysid.compare(d, m, initial="zero")
    # one sample short of the record: only the last sample sees an output, and the answer is the same
    np.testing.assert_allclose(sysid.predict(m, d, 299)[:299], sim[:299], rtol=0, atol=1e-12)


def test_long_horizon_by_fft_equals_the_direct_filters(monkeypatch):
    d = simulate_poly([1, -1.5, 0.7], [0, 1, 0.5], C=[1, 0.3], N=600, sigma=0.1, seed=7)
    m = sysid.armax(d, [2, 2, 1, 1])
    module = __import__("sys").modules["sysid.predict"]
    for k in (module.DIRECT_HORIZON + 1, 200, 599):
        fast = sysid.predict(m, d, k)
        monkeypatch.setattr(module, "DIRECT_HORIZON", 10**9)
        direct = sysid.predict(m, d, k)
        monkeypatch.undo()
        np.testing.assert_allclose(fast, direct, rtol=0, atol=1e-12 * np.max(np.abs(direct)))


def test_long_horizon_on_a_long_record_takes_milliseconds():
    """k = 10 000 on 50 000 samples: 15 s filtering with the k-term polynomials (O(N k)), 15 ms by FFT."""
    import time
    d = simulate_poly([1, -1.5, 0.7], [0, 1, 0.5], C=[1, 0.3], N=50000, sigma=0.1, seed=8)
    m = sysid.armax(d[:2000], [2, 2, 1, 1])
    t0 = time.perf_counter()
    yhat = sysid.predict(m, d, 10000)
    assert time.perf_counter() - t0 < 2.0
    np.testing.assert_allclose(yhat[:10000], sysid.simulate(m, d)[:10000], atol=1e-9)


def test_fit_percent_checks_its_arrays():
    with pytest.raises(sysid.SysidError, match="^y and yhat must have the same length"):
        sysid.fit_percent(np.arange(5.0), np.arange(4.0))
    with pytest.raises(sysid.SysidError, match="^yhat must be real"):
        sysid.fit_percent(np.arange(5.0), np.arange(5.0) + 1j)
