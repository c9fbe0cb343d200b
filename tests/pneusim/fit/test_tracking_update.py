"""The tracking filter's measurement update against filterpy's extended Kalman filter, an independent
implementation of the same equations (Joseph form), on random states and covariances."""

from types import SimpleNamespace

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from pneusim.fit.shooting import expected_position_reading
from pneusim.fit.tracking import _update

N_STATES = 5
POSITION = 0
STROKE_M = 0.2


def _filterpy_update(x, P, at, measured, sigma):
    """filterpy's update with the same measurement model: each measured value reads one state, the position
    through the saturating sensor's mean reading."""
    def readings(state):
        out = state[at].astype(float).copy()
        for i, k in enumerate(at):
            if k == POSITION:
                out[i] = expected_position_reading(state[POSITION], STROKE_M, sigma[i])[0]
        return out

    def jacobian(state):
        H = np.zeros((at.size, state.size))
        for i, k in enumerate(at):
            H[i, k] = expected_position_reading(state[POSITION], STROKE_M, sigma[i])[1] if k == POSITION else 1.0
        return H

    ekf = ExtendedKalmanFilter(dim_x=x.size, dim_z=at.size)
    ekf.x, ekf.P, ekf.R = x.copy(), P.copy(), np.diag(sigma ** 2)
    ekf.update(measured, jacobian, readings)
    return ekf.x, ekf.P, ekf.y


@pytest.mark.parametrize("at", [np.array([POSITION]), np.array([POSITION, 2, 3]), np.array([2, 4])])
@pytest.mark.parametrize("position_m", [0.1, 0.0005, 0.1998])   # mid-stroke, and near each end stop
def test_update_agrees_with_filterpy(at, position_m):
    rng = np.random.default_rng(7)
    A = rng.normal(size=(N_STATES, N_STATES))
    P = A @ A.T * 1e-4 + np.eye(N_STATES) * 1e-6
    x = rng.normal(size=N_STATES) * 1e-2
    x[POSITION] = position_m
    sigma = np.where(at == POSITION, 5e-5, 300.0 * 1e-5)
    measured = x[at] + rng.normal(size=at.size) * sigma
    state = {"x": x.copy(), "P": P.copy(), "Z": None}
    pb = SimpleNamespace(position_index=POSITION, stroke_m=STROKE_M)
    whitened, _ = _update(pb, state, at, measured, sigma)

    x_ref, P_ref, innovation = _filterpy_update(x, P, at, measured, sigma)
    assert whitened is None                                    # no sensitivities asked for
    np.testing.assert_allclose(state["x"], x_ref, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(state["P"], P_ref, rtol=1e-7, atol=1e-18)
    # the update keeps the covariance symmetric and positive definite (the Joseph form's point)
    np.testing.assert_allclose(state["P"], state["P"].T, rtol=0, atol=1e-18)
    assert np.all(np.linalg.eigvalsh(state["P"]) > 0)
    # and shrinks the variance of every measured state
    assert np.all(np.diag(state["P"])[at] < np.diag(P)[at])
    assert innovation.shape == (at.size,)


def test_whitened_innovations_have_the_innovation_covariance_removed():
    """With sensitivities, the whitened innovations are L^-1 y with S = L L^T: their sum of squares is
    y^T S^-1 y, filterpy's Mahalanobis distance squared."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(N_STATES, N_STATES))
    P = A @ A.T * 1e-4 + np.eye(N_STATES) * 1e-6
    x = rng.normal(size=N_STATES) * 1e-2
    x[POSITION] = 0.1
    at = np.array([POSITION, 2, 3])
    sigma = np.array([5e-5, 3e-3, 3e-3])
    measured = x[at] + rng.normal(size=at.size) * sigma * 4
    state = {"x": x.copy(), "P": P.copy(), "Z": rng.normal(size=(N_STATES, 2))}
    whitened, derivative = _update(SimpleNamespace(position_index=POSITION, stroke_m=STROKE_M), state, at,
                                   measured, sigma)
    ekf = ExtendedKalmanFilter(dim_x=N_STATES, dim_z=at.size)
    ekf.x, ekf.P, ekf.R = x.copy(), P.copy(), np.diag(sigma ** 2)
    H = np.eye(N_STATES)[at]
    H[0, POSITION] = expected_position_reading(x[POSITION], STROKE_M, sigma[0])[1]
    ekf.update(measured, lambda s: H,
               lambda s: np.r_[expected_position_reading(s[POSITION], STROKE_M, sigma[0])[0], s[at[1:]]])
    assert np.sum(whitened ** 2) == pytest.approx(ekf.mahalanobis ** 2, rel=1e-9)
    assert derivative.shape == (at.size, 2)
