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
