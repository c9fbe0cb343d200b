"""Known ARX/ARMAX/OE/BJ systems: truth inside the reported 3-sigma bounds over seeded trials."""
import numpy as np
import pytest

import sysid

from sysid_helpers import simulate_poly

A2 = [1.0, -1.5, 0.7]
B2 = [0.0, 1.0, 0.5]
F2 = [1.0, -1.2, 0.5]

CASES = {
    "arx": (dict(A=A2, B=B2), lambda d: sysid.arx(d, [2, 2, 1]), [-1.5, 0.7, 1.0, 0.5]),
    "armax": (dict(A=A2, B=B2, C=[1.0, -0.5, 0.2]), lambda d: sysid.armax(d, [2, 2, 2, 1]),
              [-1.5, 0.7, 1.0, 0.5, -0.5, 0.2]),
    "oe": (dict(A=[1.0], B=B2, F=F2), lambda d: sysid.oe(d, [2, 2, 1]), [1.0, 0.5, -1.2, 0.5]),
    "bj": (dict(A=[1.0], B=B2, F=F2, C=[1.0, 0.5], D=[1.0, -0.8]),
           lambda d: sysid.bj(d, [2, 1, 1, 2, 1]), [1.0, 0.5, 0.5, -0.8, -1.2, 0.5]),
}


def _zscores(case, trials, N=800, sigma=0.3):
    kw, fit, truth = CASES[case]
    z = []
    for seed in range(trials):
        d = simulate_poly(N=N, sigma=sigma, seed=100 + seed, **kw)
        m = fit(d)
        z.append((m.parameters - truth) / m.std)
    return np.array(z)


@pytest.mark.parametrize("case", list(CASES))
def test_truth_within_three_sigma(case):
    z = _zscores(case, trials=12)
    inside = np.abs(z) < 3.0
    # 99.7 % expected; allow at most 2 misses out of ~60 (would fail if sigma were 2x too small)
    assert inside.sum() >= inside.size - 2, f"{case}: {np.sum(~inside)} of {inside.size} outside 3 sigma"
    # reported sigma is not grossly pessimistic either (z would shrink towards 0)
    assert 0.5 < z.std() < 1.6, f"{case}: std of z-scores {z.std():.2f}"


def test_polynomials_are_laid_out_like_matlab():
    d = simulate_poly(A2, [0, 0, 1.0, 0.5], N=500, sigma=0.05, seed=3)
    m = sysid.arx(d, [2, 2, 2])
    assert m.B.shape == (4,) and m.B[0] == 0 and m.B[1] == 0 and m.nk == 2
    assert m.A[0] == 1.0 and m.A.shape == (3,)
    np.testing.assert_allclose(m.B[2:], [1.0, 0.5], atol=0.05)
    s = m.polynomial_std()
    assert s["B"].shape == (4,) and s["B"][0] == 0


def test_pem_reaches_lower_cost_than_its_start():
    d = simulate_poly([1.0], B2, F=F2, N=600, sigma=0.5, seed=7)
    m_arx = sysid.arx(d, [2, 2, 1])
    m_oe = sysid.oe(d, [2, 2, 1])
    assert sysid.compare(d, m_oe) > sysid.compare(d, m_arx)


def test_pem_refines_given_initial_model():
    d = simulate_poly(A2, B2, C=[1.0, -0.5, 0.2], N=800, sigma=0.3, seed=11)
    init = sysid.idpoly(A2, [0, 0.8, 0.3], C=[1, 0, 0], Ts=1.0)
    init.structure = "armax"
    m = sysid.pem(d, init)
    np.testing.assert_allclose(m.parameters, [-1.5, 0.7, 1.0, 0.5, -0.5, 0.2], atol=6 * m.std.max())
