"""Bad input gives one clear SysidError naming the argument."""
import math

import numpy as np
import pytest

import sysid
from sysid.pem import OE

from sysid_helpers import simulate_poly


def test_sysid_error_is_value_error():
    assert issubclass(sysid.SysidError, ValueError)


def test_mismatched_lengths():
    with pytest.raises(sysid.SysidError, match="same length"):
        sysid.iddata(np.zeros(10), np.zeros(9), 1.0)


def test_nan_in_output():
    y = np.zeros(10)
    y[3] = np.nan
    with pytest.raises(sysid.SysidError, match=r"y must be finite.*sample 3"):
        sysid.iddata(y, np.zeros(10), 1.0)


@pytest.mark.parametrize("ts", [0.0, -1.0, math.nan, "fast"])
def test_non_positive_sample_time(ts):
    with pytest.raises(sysid.SysidError, match="Ts must be a positive"):
        sysid.iddata(np.zeros(10), np.zeros(10), ts)


def test_orders_too_high_for_data():
    d = sysid.iddata(np.random.default_rng(0).standard_normal(20), np.ones(20), 1.0)
    with pytest.raises(sysid.SysidError, match="orders are too high"):
        sysid.arx(d, [10, 10, 1])


@pytest.mark.parametrize("orders", [[2, 2], [2, -1, 1], [2, 2.5, 1], "221"])
def test_malformed_orders(orders):
    d = simulate_poly([1, -0.5], [0, 1], N=100)
    with pytest.raises(sysid.SysidError):
        sysid.arx(d, orders)


def test_unstable_initial_model():
    d = simulate_poly([1], [0, 1], F=[1, -0.5], N=200)
    bad = sysid.idpoly([1], [0, 1], F=[1, -2.5], Ts=1.0)
    with pytest.raises(sysid.SysidError, match="init_sys must have a stable F"):
        OE(1, 1, 1, init_sys=bad).fit(d)


def test_data_must_be_iddata():
    with pytest.raises(sysid.SysidError, match="IDData"):
        sysid.arx(np.zeros((10, 2)), [1, 1, 1])


def test_bad_forgetting_and_covariance():
    with pytest.raises(sysid.SysidError, match="forgetting"):
        sysid.RecursiveARX([1, 1, 1], forgetting=1.5)
    with pytest.raises(sysid.SysidError, match="initial_covariance"):
        sysid.RecursiveARX([1, 1, 1], initial_covariance=-1)


def test_bad_prediction_horizon():
    d = simulate_poly([1, -0.5], [0, 1], N=100)
    m = sysid.arx(d, [1, 1, 1])
    with pytest.raises(sysid.SysidError, match="k must be"):
        sysid.predict(m, d, 0)


def test_rank_deficient_regressors():
    d = sysid.iddata(np.random.default_rng(0).standard_normal(100), np.ones(100), 1.0)
    with pytest.raises(sysid.SysidError, match=r"cannot support ARX\[1 2 1\].*persistently exciting"):
        sysid.arx(d, [1, 2, 1])  # constant input: u(t-1) = u(t-2)


def test_online_update_refuses_nan_and_keeps_its_state():
    est = sysid.RecursiveARX([1, 1, 1], forgetting=0.99, initial_covariance=100.0)
    for y, u in [(0.1, 1.0), (0.3, -1.0), (0.2, 1.0)]:
        est.update(y, u)
    theta, P, n = est.parameters, est.P, est.n_updates
    for y, u in [(float("nan"), 1.0), (0.1, float("inf"))]:
        with pytest.raises(sysid.SysidError, match="update needs finite y and u"):
            est.update(y, u)
    np.testing.assert_array_equal(est.parameters, theta)
    np.testing.assert_array_equal(est.P, P)
    assert est.n_updates == n


def _bad_calls():
    d = simulate_poly([1, -0.5], [0, 1], N=100)
    m = sysid.arx(d, [1, 1, 1])
    nan_u = np.ones(100)
    nan_u[7] = np.nan
    return {
        "y": lambda: sysid.iddata("abc", np.zeros(3), 1.0),
        "Ts": lambda: sysid.iddata(np.zeros(10), np.zeros(10), -0.1),
        "same length": lambda: sysid.iddata(np.zeros(10), np.zeros(9), 1.0),
        "na": lambda: sysid.arx(d, [-1, 1, 1]),
        "orders": lambda: sysid.armax(d, [1, 1, 1]),
        "k": lambda: sysid.predict(m, d, "two"),
        "u": lambda: sysid.simulate(m, nan_u),
        "initial": lambda: sysid.simulate(m, d, initial="guess"),
        "iodelay": lambda: sysid.tfest(d, 1, 0, iodelay="late"),
        "max_delay_samples": lambda: sysid.TFEst(1, 0, max_delay_samples=-2).fit(d),
        "nx": lambda: sysid.n4sid(d, 0),
        "forgetting": lambda: sysid.rls(d, [1, 1, 1], forgetting=0.0),
        "data": lambda: sysid.compare(m, d),
        "initial_covariance": lambda: sysid.rls(d, [1, 1, 1], initial_covariance=1e308),
        "max_abs_u": lambda: sysid.check_rls_options([1, 1, 1], max_abs_u=[1.0]),
        "tstart": lambda: sysid.iddata(np.zeros(10), np.zeros(10), 1.0, tstart=math.inf),
        "nk_max": lambda: sysid.delayest(d, nk_max=500),
        "yhat": lambda: sysid.fit_percent(d.y, d.y[1:]),
        "num": lambda: sysid.IDTF(np.ones(3), np.ones(2)),
        "max_iter": lambda: sysid.ARMAX(1, 1, 1, max_iter="many").fit(d),
        "tol": lambda: OE(1, 1, 1, tol=-1e-9).fit(d),
        "feedthrough": lambda: sysid.n4sid(d, 1, feedthrough="no"),
        "srivc_iterations": lambda: sysid.TFEst(1, 0, srivc_iterations="six").fit(d),
        "table": lambda: sysid.selstruc(np.zeros((2, 3))),
        "FPE": lambda: sysid.fpe(m, d[:2]),
        "order": lambda: sysid.detrend(d, True),
    }


@pytest.mark.parametrize("field", list(_bad_calls()))
def test_bad_input_is_one_sentence_naming_the_field(field):
    with pytest.raises(sysid.SysidError) as info:
        _bad_calls()[field]()
    msg = str(info.value)
    assert field in msg and msg.endswith(".") and "\n" not in msg, msg
    assert msg.count(". ") == 0, msg  # one sentence
