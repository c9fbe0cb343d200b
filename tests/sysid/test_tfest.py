"""Continuous-time transfer functions from sampled (ZOH) data."""
import numpy as np
import pytest
from scipy.signal import lfilter

import sysid
from sysid.tfest import _discretise

TS = 0.05
DEN = np.array([1.0, 1.2, 4.0])  # wn = 2 rad/s, zeta = 0.3


def _data(num, delay_samples, sigma, seed, N=2000):
    rng = np.random.default_rng(seed)
    u = np.repeat(np.sign(rng.standard_normal(N // 5)), 5)
    p = _discretise(num, DEN, TS, delay_samples)
    y = lfilter(p.B, p.F, u) + sigma * rng.standard_normal(N)
    return sysid.iddata(y, u, TS)


def test_noise_free_recovers_coefficients_and_delay():
    m = sysid.tfest(_data([8.0], 4, 0.0, 0), 2, 0)
    np.testing.assert_allclose(m.den, DEN, rtol=1e-6)
    np.testing.assert_allclose(m.num, [8.0], rtol=1e-6)
    assert m.iodelay == pytest.approx(0.2)
    assert m.dcgain() == pytest.approx(2.0)


def test_noisy_estimates_within_three_sigma_and_delay_found():
    truth = np.r_[DEN[1:], 0.5, 8.0]
    z = []
    for seed in range(6):
        m = sysid.tfest(_data([0.5, 8.0], 3, 0.1, seed), 2, 1)
        assert m.iodelay == pytest.approx(3 * TS)
        z.append((m.parameters - truth) / m.std)
    z = np.array(z)
    assert np.sum(np.abs(z) >= 3) <= 1, z
    assert z.std() < 1.6


def test_given_delay_and_simulation_fit():
    d = _data([8.0], 2, 0.05, 7)
    m = sysid.tfest(d, 2, 0, iodelay=2 * TS)
    assert m.iodelay == pytest.approx(0.1)
    assert sysid.compare(d, m) > 95.0
    assert m.to_idpoly().nk == 3
    g = sysid.to_control(m)
    assert g.dt == 0 and np.isclose(float(np.real(g(0))), m.dcgain())


def test_tfest_bad_orders():
    d = _data([8.0], 0, 0.0, 1, N=200)
    with pytest.raises(sysid.SysidError, match="nz must be smaller"):
        sysid.tfest(d, 2, 2)
    with pytest.raises(sysid.SysidError, match="iodelay"):
        sysid.tfest(d, 2, 0, iodelay=-1.0)
