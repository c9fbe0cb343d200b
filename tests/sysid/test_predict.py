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
