import math

import numpy as np
import pytest
from scipy import signal

import sysid

from sysid_helpers import simulate_poly

A, B = [1.0, -1.5, 0.7], [0.0, 0.0, 0.0, 1.0, 0.5]  # nk = 3


def test_resid_accepts_true_structure_and_rejects_wrong_one():
    d = simulate_poly([1.0], [0, 1.0, 0.5], F=[1, -1.2, 0.5], C=[1, 0.8], N=2000, sigma=0.3, seed=1)
    good = sysid.bj(d[:1000], [2, 1, 0, 2, 1])
    bad = sysid.oe(d[:1000], [2, 2, 1])  # no noise model: coloured residuals
    rg, rb = sysid.resid(d[1000:], good, skip=50), sysid.resid(d[1000:], bad, skip=50)
    assert rg.white and rg.independent
    assert not rb.white
    assert rg.bound == pytest.approx(2.5758 / math.sqrt(950), rel=1e-4)
    assert rg.autocorr[0] == pytest.approx(1.0)
    # too few input lags: residuals correlate with the input
    wrong = sysid.arx(d[:1000], [0, 1, 1])
    assert not sysid.resid(d[1000:], wrong, skip=50).independent


def test_information_criteria_formulas_and_order_choice():
    d = simulate_poly(A, B, N=1000, sigma=0.2, seed=2)
    m = sysid.arx(d, [2, 2, 3])
    V, N, dpar = m.loss, m.n_samples, 4
    assert sysid.fpe(m) == pytest.approx(V * (1 + dpar / N) / (1 - dpar / N))
    assert sysid.aic(m) == pytest.approx(N * math.log(V) + 2 * dpar + N * (math.log(2 * math.pi) + 1))
    assert sysid.bic(m) > sysid.aic(m)
    scores = {o: sysid.aic(sysid.arx(d, [o, o, 3])) for o in (1, 2, 3, 4)}
    assert min(scores, key=scores.get) == 2


def test_arxstruc_selstruc_and_delayest_find_the_structure():
    d = simulate_poly(A, B, N=2000, sigma=0.2, seed=3)
    table = sysid.arxstruc(d[:1000], d[1000:], sysid.struc(range(1, 4), range(1, 4), range(1, 6)))
    assert table.shape == (45, 5)
    na, nb, nk = sysid.selstruc(table, "mdl")
    assert (na, nb, nk) == (2, 2, 3)
    assert sysid.delayest(d) == 3


def test_poles_zeros_and_frequency_response():
    m = sysid.idpoly(A, [0, 1.0, 0.5], Ts=0.1)
    np.testing.assert_allclose(np.sort_complex(m.poles()), np.sort_complex(np.roots(A)))
    np.testing.assert_allclose(m.zeros(), [-0.5])
    w = np.array([0.1, 1.0, 10.0])
    _, h = signal.dfreqresp(sysid.to_scipy(m), w * 0.1)
    np.testing.assert_allclose(m.freqresp(w), h)


def _assert_same_model(back, m):
    np.testing.assert_allclose(back.B, m.B, atol=1e-12)
    np.testing.assert_allclose(back.F, m.F, atol=1e-12)
    assert back.nk == 2 and back.Ts == 0.01


def test_round_trip_scipy():
    m = sysid.idpoly([1.0], [0, 0, 0.3, 0.1], F=[1, -0.9, 0.2], Ts=0.01)
    _assert_same_model(sysid.from_scipy(sysid.to_scipy(m)), m)


@pytest.mark.slow          # python-control takes seconds to import
def test_round_trip_control():
    import control
    m = sysid.idpoly([1.0], [0, 0, 0.3, 0.1], F=[1, -0.9, 0.2], Ts=0.01)
    _assert_same_model(sysid.from_control(sysid.to_control(m)), m)
    g = sysid.to_control(m)
    assert g.dt == 0.01
    np.testing.assert_allclose(control.dcgain(g), 0.4 / 0.3)
    with pytest.raises(sysid.SysidError, match="discrete-time"):
        sysid.from_control(control.tf([1], [1, 1]))


def test_delay_scan_and_order_grid_beyond_the_data_are_refused():
    """nk_max or a grid order past the record would reach numpy as a 'negative dimensions' ValueError."""
    d = simulate_poly(A, B, N=100, sigma=0.2, seed=3)
    with pytest.raises(sysid.SysidError, match="^orders are too high for the data: delayest .* nk_max = 150"):
        sysid.delayest(d, nk_max=150)
    with pytest.raises(sysid.SysidError, match=r"^orders are too high for the data: validation of ARX\[2 2 60\]"):
        sysid.arxstruc(d, d[:50], [[2, 2, 60]])
    with pytest.raises(sysid.SysidError, match="^nb must be an integer"):
        sysid.arxstruc(d, d, [[2, 2.5, 1]])


def test_criteria_of_an_exact_model_are_minus_infinity():
    """V = 0 (the model reproduces the data): log V = -inf, as MATLAB, not Python's 'math domain error'."""
    d = simulate_poly([1, -0.5], [0, 1], N=200, sigma=0.0, seed=2)
    m = sysid.idpoly([1, -0.5], [0, 1])
    assert sysid.aic(m, d) == -math.inf and sysid.bic(m, d) == -math.inf and sysid.fpe(m, d) == 0.0
