"""Helpers for the sysid tests: simulated polynomial systems and the real-data folder."""
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

import sysid

REAL_DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "real"


def simulate_poly(A, B, C=(1.0,), D=(1.0,), F=(1.0,), N=1000, sigma=0.1, seed=0, Ts=1.0,
                  input_kind="prbs"):
    """Data from ``A y = B/F u + C/D e`` with a random binary input and white noise."""
    rng = np.random.default_rng(seed)
    if input_kind == "prbs":
        u = np.sign(rng.standard_normal(N))
    else:
        u = rng.standard_normal(N)
    e = sigma * rng.standard_normal(N)
    x = lfilter(B, F, u) + lfilter(C, D, e)
    y = lfilter([1.0], A, x)
    return sysid.iddata(y, u, Ts)

