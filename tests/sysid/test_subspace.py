"""Known innovations state-space systems: n4sid order, poles and 3-sigma coverage."""
import numpy as np
import pytest

import sysid
from sysid.statespace import IDSS

A_SS = np.array([[1.2, -0.6], [1.0, 0.0]])
B_SS = np.array([[1.0], [0.0]])
C_SS = np.array([[0.5, 0.3]])
K_SS = np.array([[0.4], [0.1]])


def _ss_data(seed, N=2000, sigma=0.2):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(N))
    e = sigma * rng.standard_normal(N)
    x = np.zeros(2)
    y = np.empty(N)
    for t in range(N):
        y[t] = C_SS[0] @ x + e[t]
        x = A_SS @ x + B_SS[:, 0] * u[t] + K_SS[:, 0] * e[t]
    return sysid.iddata(y, u, 0.01)


def test_truth_conversion_is_armax():
    p = IDSS(A_SS, B_SS, C_SS, np.zeros((1, 1)), K_SS, 0.01).to_idpoly()
    np.testing.assert_allclose(p.A, [1.0, -1.2, 0.6])
    np.testing.assert_allclose(np.sort(p.poles()), np.sort(np.linalg.eigvals(A_SS)))
    assert p.nk == 1 and p.C[0] == 1.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_n4sid_picks_order_and_poles(seed):
    m = sysid.n4sid(_ss_data(seed))
    assert m.nx == 2
    true = np.sort_complex(np.linalg.eigvals(A_SS))
    np.testing.assert_allclose(np.sort_complex(m.poles()), true, atol=0.02)
    assert m.singular_values[1] > 10 * m.singular_values[2]


def test_state_space_truth_within_three_sigma():
    truth = IDSS(A_SS, B_SS, C_SS, np.zeros((1, 1)), K_SS, 0.01).to_idpoly().parameters
    z = []
    for seed in range(10):
        m = sysid.armax(_ss_data(50 + seed), [2, 2, 2, 1])
        z.append((m.parameters - truth) / m.std)
    z = np.array(z)
    assert np.sum(np.abs(z) >= 3) <= 1, z
    assert 0.5 < z.std() < 1.6


def test_n4sid_fit_close_to_true_system():
    d = _ss_data(9, N=3000)
    true = IDSS(A_SS, B_SS, C_SS, np.zeros((1, 1)), K_SS, 0.01)
    m = sysid.n4sid(d[:2000], 2)
    val = d[2000:]
    assert sysid.compare(val, m, k=1) > sysid.compare(val, true, k=1) - 0.5
    assert sysid.compare(val, m) > sysid.compare(val, true) - 0.5


def test_n4sid_rejects_too_short_data():
    d = _ss_data(0, N=40)
    with pytest.raises(sysid.SysidError, match="orders are too high"):
        sysid.n4sid(d, 4)
