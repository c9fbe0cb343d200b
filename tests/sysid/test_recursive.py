"""RLS on the 4th-order pneumatic model of the online-identification paper (its eq. 10)."""
import math

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


@pytest.mark.parametrize("lam,c", [(1.0, 1e8), (0.999, 1e4)])
def test_noisy_estimate_within_reported_three_sigma(lam, c):
    """Repeated seeded trials: the truth lies within the estimator's own 3-sigma bounds.

    With lambda = 1 the prior P0 = c I never fades (bias ~ P theta / c), so c is large;
    with lambda < 1 it is forgotten and the paper's c = 1e4 is used.
    """
    sigma = 2e-4
    z, s2 = [], []
    for seed in range(8):
        res = sysid.rls(_eq10_data(N=6000, sigma=sigma, seed=seed), ORDERS, forgetting=lam,
                        initial_covariance=c)
        z.append((res.theta_ - THETA10) / res.std)
        s2.append(res.noise_variance)
        assert np.max(np.abs(res.theta_ - THETA10)) > 1e-7  # noise really perturbs the estimate
    z = np.array(z)
    inside = np.abs(z) < 3.0
    assert inside.sum() >= inside.size - 2, f"{np.sum(~inside)} of {inside.size} outside 3 sigma: {z}"
    assert 0.5 < z.std() < 1.6, z.std()  # the bounds are neither too tight nor far too wide
    assert np.sqrt(np.mean(s2)) == pytest.approx(sigma, rel=0.1)  # reported noise level


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
        # after the transient the error decays like lambda^tau: log-slope / ln(lambda) = 1
        r = err[t0:] / err[t0 - 1]
        tail = np.flatnonzero((r < 0.5) & (r > 1e-3))
        slope = np.polyfit(tail, np.log(r[tail]), 1)[0]
        assert slope / np.log(lam) == pytest.approx(1.0, abs=0.1), (lam, slope)
    ratios = np.array(list(settle.values()))
    assert np.all((ratios > 3) & (ratios < 20)), settle
    assert ratios.max() / ratios.min() < 1.2, settle


@pytest.mark.filterwarnings("ignore:final RLS model:sysid.SysidWarning")   # 300 samples: the prior still holds 4.5 %
def test_online_update_matches_batch_and_returns_prior_error():
    data = _eq10_data(N=300, sigma=1e-3, seed=5)
    est = sysid.RecursiveARX(ORDERS, forgetting=0.98, initial_covariance=1000.0)
    errs = [est.update(y, u) for y, u in zip(data.y, data.u)]
    res = sysid.rls(data, ORDERS, forgetting=0.98, initial_covariance=1000.0)
    np.testing.assert_allclose(est.parameters, res.theta_, rtol=1e-12)
    np.testing.assert_allclose(errs, res.errors_, rtol=1e-12)
    assert errs[0] == data.y[0]  # theta(0) = 0


def _paper_recursion(y, u, na, nb, nc, nk, lam, c):
    """Eq. (8) of the paper written out plainly (no scaling tricks): the reference."""
    d = na + nb + nc
    theta, P = np.zeros(d), c * np.eye(d)
    ypad, upad, epad = np.zeros(na) , np.zeros(nk + nb), np.zeros(nc)
    hist = np.empty((y.size, d))
    for t in range(y.size):
        upad = np.r_[u[t], upad[:-1]] if upad.size else upad
        psi = np.r_[-ypad, upad[nk:nk + nb], epad]
        den = lam + psi @ P @ psi
        theta = theta + P @ psi * (y[t] - psi @ theta) / den
        P = (P - np.outer(P @ psi, psi @ P) / den) / lam
        ypad = np.r_[y[t], ypad[:-1]][:na]
        if nc:
            epad = np.r_[y[t] - psi @ theta, epad[:-1]]
        hist[t] = theta
    return hist


@pytest.mark.parametrize("orders,lam", [([4, 4, 0], 0.95), ([2, 2, 2, 1], 0.95), ([2, 3, 1, 2], 0.99)])
def test_matches_plain_paper_recursion_over_long_records(orders, lam):
    """Same numbers as eq. (8) written plainly, also past the internal rescaling (~6700 samples at 0.95)."""
    rng = np.random.default_rng(9)
    N = 8000
    u = rng.standard_normal(N)
    y = lfilter(B10, A10, u) + lfilter([1.0, 0.5], A10, 1e-3 * rng.standard_normal(N))
    na, nb, nc, nk = (orders[0], orders[1], 0, orders[2]) if len(orders) == 3 else orders
    ref = _paper_recursion(y, u, na, nb, nc, nk, lam, 1000.0)
    res = sysid.rls(sysid.iddata(y, u, 1e-3), orders, forgetting=lam, initial_covariance=1000.0)
    np.testing.assert_allclose(res.theta_history, ref, rtol=1e-6, atol=1e-9)


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


# ------------------------------------------------------------------ settings that cannot give an estimate
def _second_order(N=1000, seed=0):
    """``A = [1, -1.5, 0.7]``, ``B = [0, 1, 0.5]``, PRBS input, output up to about 13."""
    from sysid_helpers import simulate_poly
    return simulate_poly([1, -1.5, 0.7], [0, 1, 0.5], N=N, sigma=0.1, seed=seed)


def _c_limit(data, lam=1.0):
    """Largest c that check_rls_options lets [2 2 1] RLS use on ``data``: c |psi|^2 < lambda / eps."""
    psi2 = 2 * np.max(np.abs(data.y)) ** 2 + 2 * np.max(np.abs(data.u)) ** 2
    return lam / np.finfo(float).eps / psi2


@pytest.mark.parametrize("c", [1e308, 1e100, 1e16])
def test_initial_covariance_beyond_the_digits_of_P_is_refused(c):
    """Unchecked, c = 1e308 gives A = [1, -0.141, 0] (truth [1, -1.5, 0.7]) without a word: c |psi|^2 overflows."""
    with pytest.raises(sysid.SysidError, match=r"^initial_covariance c = .* too large for signals up to .*"
                                               r"expected c < "):
        sysid.rls(_second_order(), [2, 2, 1], initial_covariance=c)


def test_initial_covariance_limit_is_where_the_first_update_keeps_no_digit():
    data = _second_order()
    limit = _c_limit(data)
    with pytest.raises(sysid.SysidError, match="initial_covariance"):
        sysid.rls(data, [2, 2, 1], initial_covariance=1.01 * limit)
    res = sysid.rls(data, [2, 2, 1], initial_covariance=0.5 * limit)
    np.testing.assert_allclose(res.model_.A, [1, -1.5, 0.7], atol=0.02)
    assert res.model_.warnings == []


@pytest.mark.parametrize("orders,d", [([2, 2, 1], 4), ([0, 1, 1], 1), ([4, 4, 0], 8), ([2, 2, 2, 1], 6)])
def test_forgetting_with_a_memory_shorter_than_the_parameters_is_refused(orders, d):
    """Unchecked, forgetting = 1e-300 ends in ZeroDivisionError, 1e-3 in NaN: the memory 1/(1 - lambda) must hold d + 1."""
    data = _second_order()
    low = d / (d + 1)
    for lam in (1e-300, 1e-3, low * (1 - 1e-9)):
        with pytest.raises(sysid.SysidError, match=rf"^forgetting must be in \[{low:.4g}, 1\] for {d} parameters"):
            sysid.rls(data, orders, forgetting=lam)
    res = sysid.rls(data, orders, forgetting=low)          # the limit itself is accepted
    assert np.all(np.isfinite(res.theta_history)) and np.isfinite(res.noise_variance)


def test_check_rls_options_is_the_recursions_validation():
    assert sysid.check_rls_options([3, 3, 1], 0.99, 1000.0) == ((3, 3, 0, 1), 0.99, 1000.0)
    assert sysid.check_rls_options([2, 2, 1, 1], np.float64(1.0), 10) == ((2, 2, 1, 1), 1.0, 10.0)
    for kwargs, name in [(dict(forgetting=True), "forgetting"), (dict(forgetting="0.99"), "forgetting"),
                         (dict(forgetting=0.5), "forgetting"), (dict(initial_covariance=math.inf), "initial_covariance"),
                         (dict(initial_covariance=1 + 0j), "initial_covariance"),
                         (dict(initial_covariance=0.0), "initial_covariance"),
                         (dict(max_abs_y=0.1, max_abs_u=10.0, initial_covariance=1e15), "initial_covariance"),
                         (dict(max_abs_y="big"), "max_abs_y")]:
        with pytest.raises(sysid.SysidError, match=f"^{name}"):
            sysid.check_rls_options([3, 3, 1], **kwargs)
    # the paper's settings on paper 1's signals (position up to 0.1 m, valve command up to 10 V) pass
    sysid.check_rls_options([5, 5, 1], 0.95, 10000.0, max_abs_y=0.1, max_abs_u=10.0)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")   # numpy says it before sysid does
def test_online_update_that_would_overflow_is_refused_and_changes_nothing():
    est = sysid.RecursiveARX([2, 2, 1], initial_covariance=1e308)
    est.update(10.0, 1.0)                      # psi = 0: nothing to overflow yet
    theta, P, psi, ud, n = est.parameters, est.P, est._psi.copy(), list(est._udelay), est.n_updates
    with pytest.raises(sysid.SysidError, match=r"^update: psi\^T P psi overflows at sample 1 .*initial_covariance"):
        est.update(12.0, 2.0)
    np.testing.assert_array_equal(est.parameters, theta)
    np.testing.assert_array_equal(est.P, P)
    np.testing.assert_array_equal(est._psi, psi)
    assert list(est._udelay) == ud and est.n_updates == n


def test_online_update_says_once_when_P_has_no_digit_left():
    data = _second_order(N=200)
    est = sysid.RecursiveARX([2, 2, 1], initial_covariance=1e20)
    with pytest.warns(sysid.SysidWarning, match="cancels all 16 digits of P") as record:
        est.partial_fit(data)
    assert len([w for w in record if issubclass(w.category, sysid.SysidWarning)]) == 1
    assert len(est.warnings) == 1 and "initial_covariance" in est.warnings[0]


def test_covariance_windup_is_said_in_the_models_warnings():
    """600 samples of constant input at forgetting 0.9: P grows by 0.9^-600 where u does not excite."""
    rng = np.random.default_rng(0)
    u = np.r_[np.sign(rng.standard_normal(300)), np.ones(600), np.sign(rng.standard_normal(300))]
    y = lfilter([0, 1, 0.5], [1, -1.5, 0.7], u) + 0.01 * rng.standard_normal(u.size)
    with pytest.warns(sysid.SysidWarning, match="grows like forgetting"):
        res = sysid.rls(sysid.iddata(y, u, 1.0), [2, 2, 1], forgetting=0.9)
    assert any("cancels all 16 digits" in w for w in res.model_.warnings)


@pytest.mark.parametrize("y,u,name", [(1 + 1j, 1.0, "y"), (0.5, np.complex128(1.0), "u"),
                                      (np.array([1 + 0j]), 1.0, "y"), (True, 1.0, "y")])
def test_online_update_refuses_a_complex_sample_in_one_line(y, u, name):
    est = sysid.RecursiveARX([1, 1, 1])
    with pytest.raises(sysid.SysidError, match=f"^update: {name} must be one real number"):
        est.update(y, u)
    assert est.n_updates == 0 and not np.any(est.parameters)


def test_online_update_takes_numpy_scalars_and_ints_as_the_same_floats():
    data = _second_order(N=100)
    a = sysid.RecursiveARX([2, 2, 1], forgetting=0.99)
    b = sysid.RecursiveARX([2, 2, 1], forgetting=0.99)
    for yk, uk in zip(data.y, data.u):
        a.update(float(yk), float(uk))
        b.update(np.float64(yk), np.int64(uk))       # the input is +-1
    np.testing.assert_array_equal(a.parameters, b.parameters)


def test_recursive_sample_time_and_orders_are_checked():
    with pytest.raises(sysid.SysidError, match="Ts must be a positive number of seconds"):
        sysid.RecursiveARX([1, 1, 1], Ts=True)
    with pytest.raises(sysid.SysidError, match="initial_parameters must be 2 finite real numbers"):
        sysid.RecursiveARX([1, 1, 1], initial_parameters=[0.5, np.nan])
    huge = sysid.iddata(1e160 * np.sin(np.arange(50.0)), np.ones(50), 1.0)
    with pytest.raises(sysid.SysidError, match=r"^signals up to \|y\| = .* too large for recursive least squares"):
        sysid.rls(huge, [1, 1, 1])
    short = sysid.iddata(np.arange(10.0), np.ones(10), 1.0)
    with pytest.raises(sysid.SysidError, match=r"orders are too high for the data: rls with orders \[5, 5, 1\]"):
        sysid.rls(short, [5, 5, 1])


def test_a_prior_that_still_weighs_in_the_final_estimate_is_said():
    """The same record in km instead of m: c = 1000 is then a strong prior on the a's (|y| ~ 0.01), and the
    estimate is pulled towards theta(0) = 0 (a1 = -1.28 for -1.5) -- said, with the prior's share."""
    data = _second_order(N=3000)
    assert sysid.rls(data, [2, 2, 1]).model_.warnings == []
    small = sysid.iddata(data.y * 1e-3, data.u, 1.0)
    with pytest.warns(sysid.SysidWarning, match=r"the prior P\(0\) = c I still holds 1\d\.?\d* % of the weight"):
        res = sysid.rls(small, [2, 2, 1])
    assert abs(res.model_.A[1] + 1.5) > 0.1                   # the pull is real
    assert any("initial_covariance" in w for w in res.model_.warnings)
    assert sysid.rls(small, [2, 2, 1], initial_covariance=1e7).model_.warnings == []
