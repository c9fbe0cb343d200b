"""No wrong answer without a word, no traceback for a user mistake.

The closed-loop recording is paper 2's multisine in its position loop
(``pneusim simulate --rig paper2-enfield --input multisine --loop closed --seed 1``).
"""
import math
import warnings

import numpy as np
import pytest
from scipy import signal

import sysid
from sysid._diagnose import problems
from sysid.tfest import IDTF

from sysid_helpers import simulate_poly


@pytest.fixture(scope="module")
def loop_data(tmp_path_factory):
    pneusim = pytest.importorskip("pneusim")
    from pneusim.experiment import standard_experiment
    from pneusim.recording import write_recording
    from pneusim.rig import load_rig
    from pneusim.simulate import simulate
    rig = load_rig("paper2-enfield")
    exp = standard_experiment(rig, "multisine", duration_s=80.0, loop="closed", seed=1)
    path = tmp_path_factory.mktemp("loop") / "run.csv"
    write_recording(simulate(rig, exp, seed=1).recording, path)
    assert pneusim
    return path


@pytest.mark.parametrize("nx", [2, 3, 4])
def test_fixed_order_n4sid_on_closed_loop_recording(loop_data, nx):
    """A stable or marginal A and a B that is not numerically zero (open-loop-biased estimates of these data have
    |z| 1.02-1.06, B 1e-47..1e-131 and compare about 0 %)."""
    est, val = sysid.load_recording(loop_data).detrend().split(6000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sysid.SysidWarning)   # order 2 keeps a 1.0012 integrator: said
        m = sysid.n4sid(est, nx)
    assert np.max(np.abs(m.poles())) < 1.002
    assert np.max(np.abs(m.to_idpoly().B)) > 1e-4             # m/V per sample: not numerically zero
    assert sysid.compare(val, m) > 85.0                       # a biased estimate: -0.2 to -0.4 %
    assert m.report["fit_percent"] > 80.0
    for msg in m.warnings:
        assert "unstable" in msg


def test_unstable_arx_warns_and_compare_says_why(loop_data):
    """Not detrended, first 6000 samples: ARX[3 3 1] has a pole at 1.95 (compare says why it cannot simulate it)."""
    data = sysid.load_recording(loop_data)
    est, val = data[:6000], data[6000:]
    with pytest.warns(sysid.SysidWarning, match=r"ARX\[3 3 1\] model is unstable"):
        m = sysid.arx(est, [3, 3, 1])
    assert any("unstable" in w for w in m.warnings)
    with pytest.raises(sysid.SysidError, match="unstable.*overflows"):
        sysid.compare(val, m, initial="estimate")
    assert math.isfinite(sysid.compare(val, m, k=1))          # prediction still works


def test_degenerate_and_nonfinite_models_are_named():
    d = simulate_poly([1, -0.5], [0, 1], N=300, seed=1)
    tiny = sysid.idpoly([1, -0.5], [0, 1e-131])
    assert any("B = 0" in w for w in problems(tiny, d.y, d.u, "model"))
    bad = sysid.idpoly([1, -0.5], [0, np.nan])
    assert any("non-finite" in w for w in problems(bad, d.y, d.u, "model"))
    assert problems(sysid.idpoly([1, -0.5], [0, 1]), d.y, d.u, "model") == []


def test_compare_estimates_initial_conditions_by_default():
    d0 = simulate_poly([1, -0.95], [0, 1], N=400, sigma=0.0, seed=5)
    d = sysid.iddata(d0.y + 5.0 * 0.95 ** np.arange(1, 401), d0.u, 1.0)
    m = sysid.idpoly([1, -0.95], [0, 1])
    assert sysid.compare(d, m) == pytest.approx(100.0, abs=1e-6)
    assert sysid.compare(d, m) == sysid.compare(d, m, initial="estimate")
    assert sysid.compare(d, m, initial="zero") < 99.0


def test_compare_refuses_other_sample_time():
    d = simulate_poly([1, -0.8], [0, 1], N=300, seed=2, Ts=0.02)
    m = sysid.arx(sysid.iddata(d.y, d.u, 0.01), [1, 1, 1])
    with pytest.raises(sysid.SysidError, match="sampled at Ts = 0.01 s but the data at Ts = 0.02 s"):
        sysid.compare(d, m)
    g = IDTF(np.array([1.0]), np.array([1.0, 1.0]), iodelay=0.0, Ts=0.01)   # continuous: re-sampled
    assert math.isfinite(sysid.compare(d, g))


def test_compare_constant_output_is_a_clear_error():
    d = sysid.iddata(np.full(100, 0.25), np.sign(np.sin(np.arange(100.0))), 0.01)
    m = sysid.idpoly([1, -0.5], [0, 1], Ts=0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                        # no RuntimeWarning either
        with pytest.raises(sysid.SysidError, match="y is constant.*undefined"):
            sysid.compare(d, m)


def test_armax_on_huge_data_scales_or_refuses():
    d = simulate_poly([1, -1.5, 0.7], [0, 1, 0.5], C=[1, -0.5, 0.2], N=800, sigma=0.3, seed=3)
    with pytest.raises(sysid.SysidError, match="y has an RMS of .*floating-point range"):
        sysid.armax(sysid.iddata(d.y * 1e200, d.u * 1e200, 1.0), [2, 2, 2, 1])
    m, mb = sysid.armax(d, [2, 2, 2, 1]), sysid.armax(sysid.iddata(d.y * 1e120, d.u * 1e100, 1.0), [2, 2, 2, 1])
    np.testing.assert_allclose(mb.A, m.A, rtol=1e-8)
    np.testing.assert_allclose(mb.B, m.B * 1e20, rtol=1e-8)
    np.testing.assert_allclose(mb.std[:2], m.std[:2], rtol=1e-6)


@pytest.mark.parametrize("args,name", [(("1", "x"), "y"), ((1.0, None), "u"), ((np.ones(3), 1.0), "y")])
def test_recursive_update_names_the_bad_argument(args, name):
    r = sysid.RecursiveARX([2, 2, 1])
    with pytest.raises(sysid.SysidError, match=f"update: {name} must be one real number"):
        r.update(*args)
    assert r.n_updates == 0


def test_models_print_like_matlab(loop_data):
    est = sysid.load_recording(loop_data).detrend()[:3000]
    m = sysid.n4sid(est, 7, weighting="moesp", horizon=10)     # order 7: matrices summarised
    text = repr(m)
    assert text.startswith("Discrete-time identified state-space model:")
    assert "Sample time: 0.01 seconds" in text and "Fit to estimation data:" in text
    assert "A: 7x7 matrix" in text and len(text.splitlines()) < 40
    g = sysid.tfest(est[:600], 2, 1, iodelay=0.03)
    gt = str(g)
    assert gt.startswith("Continuous-time identified transfer function.") and "Input delay:" in gt
    assert len(gt.splitlines()) < 25
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sysid.SysidWarning)    # a 1.0002 integrator: said, not tested here
        arx = sysid.arx(est, [2, 2, 1])
    assert str(arx).startswith("Discrete-time ARX model: A(z)y(t) = B(z)u(t) + e(t)")


def test_delay_is_carried_or_refused_in_conversions():
    g = IDTF(np.array([2.0]), np.array([1.0, 3.0, 2.0]), iodelay=0.05, Ts=0.01)
    for conv in (sysid.to_scipy, sysid.to_control):
        with pytest.raises(sysid.SysidError, match="input delay of 0.05 s.*pade_order"):
            conv(g)
    w = np.array([0.5, 2.0, 5.0])
    exact = g.freqresp(w)
    _, h = signal.freqresp(sysid.to_scipy(g, pade_order=3), w)
    np.testing.assert_allclose(h, exact, rtol=1e-4)
    c = sysid.to_control(g, pade_order=3)
    np.testing.assert_allclose(c(1j * w), exact, rtol=1e-4)
    dz = sysid.to_scipy(g, discrete=True)                      # exact ZOH, delay as 5 samples
    _, yimp = signal.dimpulse(dz, n=8)
    assert np.all(np.ravel(yimp)[:6] == 0.0) and np.ravel(yimp)[6] > 0


def test_n4sid_keeps_an_unstable_system_the_data_show_and_says_so():
    """Poles 1.01 and 0.7 over 400 samples (growth 53x): the reflected twin simulates the data at -38 %,
    so the unstable estimate is kept (the data say so), with a warning; enforce_stability=True reflects."""
    rng = np.random.default_rng(3)
    u = np.sign(rng.standard_normal(400))
    y = signal.lfilter([0, 1.0, 0.5], [1, -1.71, 0.707], u) + 0.01 * rng.standard_normal(400)
    d = sysid.iddata(y, u, 0.01)
    with pytest.warns(sysid.SysidWarning, match=r"unstable: a pole has \|z\| = 1.01"):
        m = sysid.n4sid(d, 2)
    np.testing.assert_allclose(np.sort(np.abs(m.poles())), [0.7, 1.01], atol=1e-3)
    assert not m.report["stability_enforced"]
    assert np.max(np.abs(sysid.n4sid(d, 2, enforce_stability=True).poles())) < 1.0
    with pytest.raises(sysid.SysidError, match="weighting must be"):
        sysid.n4sid(d, 2, weighting="cva")
