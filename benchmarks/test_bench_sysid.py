"""Benchmarks of sysid estimators on 8000 samples, side by side with SIPPY where it has the method.

Run: ``python -m pytest benchmarks/test_bench_sysid.py --benchmark-only``.
Targets (not asserted, machines differ): arx < 5 ms; armax, n4sid < 0.5 s;
``RecursiveARX.update`` < 10 us for 10 parameters (100x real time at 1 kHz).
BLAS threads compete with each other on small problems: set
``OPENBLAS_NUM_THREADS=1`` for stable numbers.
"""
import contextlib
import io

import numpy as np
import pytest
from scipy.signal import lfilter

import sysid

N = 8000


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal(N))
    e = 0.3 * rng.standard_normal(N)
    A, B, C = [1.0, -1.5, 0.7], [0.0, 1.0, 0.5], [1.0, -0.5, 0.2]
    y = lfilter(B, A, u) + lfilter(C, A, e)
    return sysid.iddata(y, u, 0.01)


@pytest.fixture(scope="module")
def ct_data():
    from sysid.tfest import _discretise
    rng = np.random.default_rng(1)
    u = np.repeat(np.sign(rng.standard_normal(N // 5)), 5)
    p = _discretise([8.0], [1.0, 1.2, 4.0], 0.05, 4)
    return sysid.iddata(lfilter(p.B, p.F, u) + 0.05 * rng.standard_normal(N), u, 0.05)


def _sippy(*args, **kw):
    sippy = pytest.importorskip("sippy_unipi", reason="SIPPY (pip install sippy-unipi) is not installed")
    with contextlib.redirect_stdout(io.StringIO()):
        return sippy.system_identification(*args, **kw)


@pytest.mark.benchmark(group="arx")
def test_arx_sysid(benchmark, data):
    m = benchmark(sysid.arx, data, [2, 2, 1])
    assert abs(m.A[1] + 1.5) < 0.1


@pytest.mark.benchmark(group="arx")
def test_arx_sippy(benchmark, data):
    benchmark(_sippy, data.y, data.u, "ARX", ARX_orders=[2, 2, 0])


@pytest.mark.benchmark(group="armax")
def test_armax_sysid(benchmark, data):
    m = benchmark(sysid.armax, data, [2, 2, 2, 1])
    assert abs(m.C[1] + 0.5) < 0.1


@pytest.mark.benchmark(group="armax")
def test_armax_sippy(benchmark, data):
    benchmark(_sippy, data.y, data.u, "ARMAX", ARMAX_orders=[2, 2, 2, 0])


@pytest.mark.benchmark(group="n4sid")
def test_n4sid_sysid(benchmark, data):
    m = benchmark(sysid.n4sid, data, 2)
    assert m.nx == 2


@pytest.mark.benchmark(group="n4sid")
def test_n4sid_sippy(benchmark, data):
    benchmark(_sippy, data.y, data.u, "N4SID", SS_fixed_order=2)


@pytest.mark.benchmark(group="tfest")
def test_tfest_sysid(benchmark, ct_data):
    m = benchmark.pedantic(sysid.tfest, args=(ct_data, 2, 0), rounds=3, iterations=1)
    assert abs(m.iodelay - 0.2) < 1e-9


@pytest.mark.benchmark(group="rls")
def test_rls_update_5th_order(benchmark):
    """One update of a 5th-order model with 10 parameters ([na nb nk] = [5 5 1])."""
    est = sysid.RecursiveARX([5, 5, 1], forgetting=0.99, initial_covariance=1000.0)
    rng = np.random.default_rng(2)
    for y, u in zip(rng.standard_normal(100).tolist(), rng.standard_normal(100).tolist()):
        est.update(y, u)
    benchmark(est.update, 0.3, -0.2)
    assert est.d == 10


@pytest.mark.benchmark(group="rls")
def test_rls_whole_record(benchmark, data):
    res = benchmark(sysid.rls, data, [2, 2, 1], forgetting=1.0, initial_covariance=1000.0)
    assert res.theta_history.shape == (N, 4)


@pytest.mark.benchmark(group="rls")
def test_rls_sippy_whole_record(benchmark, data):
    benchmark(_sippy, data.y, data.u, "ARX", ARX_orders=[2, 2, 0], ARX_mod="RLLS")
