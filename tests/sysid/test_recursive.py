"""RLS on the 4th-order pneumatic model of the online-identification paper (its eq. 10)."""
import numpy as np
import pytest
from scipy.signal import lfilter

import sysid
from sysid.arx import arx_regressors

# eq. (10): G = (0.0070699 z^4 - 0.017738 z^3 + 0.019649 z^2 + 0.00027783 z)
#               / (z^4 - 1.9827 z^3 + 1.2989 z^2 - 0.43504 z + 0.12436), i.e. nk = 0 in q^-1
A10 = np.array([1.0, -1.9827, 1.2989, -0.43504, 0.12436])
B10 = np.array([0.0070699, -0.017738, 0.019649, 0.00027783])
THETA10 = np.r_[A10[1:], B10]
ORDERS = [4, 4, 0]


def _eq10_data(N=3000, sigma=0.0, seed=0, B_after=None, t_switch=None):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    e = sigma * rng.standard_normal(N)
    if B_after is None:
        y = lfilter(B10, A10, u) + lfilter([1.0], A10, e)
    else:  # coefficients of B change at t_switch, state carried over
        x = np.where(np.arange(N) < t_switch, lfilter(B10, [1.0], u), lfilter(B_after, [1.0], u))
        y = lfilter([1.0], A10, x + e)
    return sysid.iddata(y, u, 1e-3)


def test_noise_free_converges_to_paper_coefficients():
    res = sysid.rls(_eq10_data(), ORDERS, forgetting=0.99, initial_covariance=1e4)
    assert res.theta_history.shape == (3000, 8)
    np.testing.assert_allclose(res.theta_, THETA10, atol=1e-6)
    np.testing.assert_allclose(res.model_.A, A10, atol=1e-6)
    np.testing.assert_allclose(res.model_.B, B10, atol=1e-6)
    # before enough data the estimate is not yet there (the test can fail)
    assert np.max(np.abs(res.theta_history[5] - THETA10)) > 1e-3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noisy_estimate_within_three_sigma(seed):
    sigma = 2e-4
    data = _eq10_data(N=6000, sigma=sigma, seed=seed)
    # lambda = 1: P = (Phi^T Phi + I/c)^-1; a large c keeps the prior's bias negligible
    res = sysid.rls(data, ORDERS, forgetting=1.0, initial_covariance=1e8)
    std = np.sqrt(sigma**2 * np.diag(res.estimator_.P))
    z = (res.theta_ - THETA10) / std
    assert np.all(np.abs(z) < 3.5), z
    assert np.max(np.abs(res.theta_ - THETA10)) > 1e-7  # noise really perturbs the estimate


def test_rls_equals_exponentially_weighted_least_squares():
    """theta(t) = argmin sum lambda^(t-s) eps_s^2 + lambda^(t+1) |theta|^2 / c (exact)."""
    lam, c = 0.97, 100.0
    data = _eq10_data(N=400, sigma=1e-3, seed=4)
    res = sysid.rls(data, ORDERS, forgetting=lam, initial_covariance=c)
    Phi, tgt, _ = arx_regressors(np.r_[np.zeros(4), data.y], np.r_[np.zeros(4), data.u], 4, 4, 0)
    for T in (50, 199, 399):
        w = lam ** (T - np.arange(T + 1))
        R = (Phi[:T + 1] * w[:, None]).T @ Phi[:T + 1] + lam ** (T + 1) * np.eye(8) / c
        theta = np.linalg.solve(R, (Phi[:T + 1] * w[:, None]).T @ tgt[:T + 1])
        np.testing.assert_allclose(res.theta_history[T], theta, rtol=1e-6, atol=1e-9)


def test_tracks_step_change_at_forgetting_rate():
    """Settling time after a coefficient step scales like the memory 1/(1 - lambda)."""
    t0 = 2000
    B_new = 1.5 * B10
    data = _eq10_data(N=5000, B_after=B_new, t_switch=t0)
    theta_new = np.r_[A10[1:], B_new]
    settle = {}
    for lam in (0.98, 0.99, 0.995):
        res = sysid.rls(data, ORDERS, forgetting=lam, initial_covariance=1e4)
        err = np.linalg.norm(res.theta_history - theta_new, axis=1)
        assert err[t0 - 1] == pytest.approx(np.linalg.norm(B_new - B10), rel=1e-3)  # tracked old one
        late = np.flatnonzero(err[t0:] > 0.1 * err[t0 - 1])
        settle[lam] = (late[-1] + 1) * (1 - lam)  # in memory lengths
        assert err[-1] < 1e-3 * err[t0 - 1]  # converges to the new coefficients
    ratios = np.array(list(settle.values()))
    assert np.all((ratios > 3) & (ratios < 20)), settle
    assert ratios.max() / ratios.min() < 1.2, settle


def test_online_update_matches_batch_and_returns_prior_error():
    data = _eq10_data(N=300, sigma=1e-3, seed=5)
    est = sysid.RecursiveARX(ORDERS, forgetting=0.98, initial_covariance=1000.0)
    errs = [est.update(y, u) for y, u in zip(data.y, data.u)]
    res = sysid.rls(data, ORDERS, forgetting=0.98, initial_covariance=1000.0)
    np.testing.assert_allclose(est.parameters, res.theta_, rtol=1e-12)
    np.testing.assert_allclose(errs, res.errors_, rtol=1e-12)
    assert errs[0] == data.y[0]  # theta(0) = 0


def test_extended_least_squares_armax():
    rng = np.random.default_rng(6)
    N = 20000
    u = np.sign(rng.standard_normal(N))
    e = 0.3 * rng.standard_normal(N)
    A, B, C = [1, -1.5, 0.7], [0, 1.0, 0.5], [1, -0.5, 0.2]
    y = lfilter(B, A, u) + lfilter(C, A, e)
    res = sysid.rls(sysid.iddata(y, u, 1.0), [2, 2, 2, 1], forgetting=1.0, initial_covariance=100.0)
    np.testing.assert_allclose(res.theta_, [-1.5, 0.7, 1.0, 0.5, -0.5, 0.2], atol=0.05)
    assert res.model_.C.shape == (3,)
    # plain RLS (ARX) on the same data is biased in a, which ELS removes
    arx_only = sysid.rls(sysid.iddata(y, u, 1.0), [2, 2, 1], forgetting=1.0, initial_covariance=100.0)
    assert abs(arx_only.theta_[0] + 1.5) > abs(res.theta_[0] + 1.5)
