"""The tracking filter's compiled pass (:mod:`pneusim.fit._filter`) against filterpy's extended Kalman filter, an
independent implementation of the same equations (prediction ``F P F^T + Q``, update in Joseph form), over
sequences of a model whose one-sample step and sensitivities are known exactly; its innovations' Jacobian
against finite differences; its sensor reading against the Python function the shooting problem uses."""

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from pneusim.fit._filter import expected_reading, filter_pass
from pneusim.fit.shooting import expected_position_reading

N_STATES = 5
N_FREE = 2
POSITION = 0
STROKE_M = 0.2
X_SCALE = np.array([0.2, 1.0, 1e5, 1e5, 0.5])


class StepFailed(Exception):
    pass


def _model(seed, nonlinear):
    """A one-sample map ``x -> A x + B theta (+ 0.02 sin x)`` near mid-stroke and its sensitivities."""
    rng = np.random.default_rng(seed)
    A = np.eye(N_STATES) * 0.9 + rng.normal(size=(N_STATES, N_STATES)) * 0.05
    A *= X_SCALE[:, None] / X_SCALE[None, :]          # the states' magnitudes differ, as the rig's do
    B = rng.normal(size=(N_STATES, N_FREE)) * X_SCALE[:, None] * 0.01
    offset = np.array([0.1, 0.0, 3e5, 3e5, 0.0]) * (1 - 0.9)   # keeps the position near 0.1 m

    def f(x, theta):
        out = A @ x + B @ theta + offset
        if nonlinear:
            out = out + 0.02 * X_SCALE * np.sin(x / X_SCALE)
        return out

    def F(x):
        return A + (np.diag(0.02 * np.cos(x / X_SCALE)) if nonlinear else 0.0)
    return f, F, B


def _measurements(f, theta, at, sigma, n_samples, seed):
    rng = np.random.default_rng(seed)
    x = np.array([0.1, 0.0, 3e5, 3e5, 0.0])
    truth = []
    for _ in range(n_samples):
        truth.append(x)
        x = f(x, theta) + rng.normal(size=N_STATES) * X_SCALE * 1e-3
    truth = np.array(truth)
    return truth[:, at] + rng.normal(size=(n_samples, at.size)) * sigma


def _run_pass(f, F, B, theta, x_first, values, at, sigma, seen, process_var, P0, gradients=True):
    def step(t0, x, schedule, x_buffer, s_buffer):
        x_buffer[1] = f(x, theta)
        s_buffer[1, :, :N_FREE] = B
        s_buffer[1, :, N_FREE:] = F(x) * X_SCALE[None, :]   # the simulator's state columns are scaled

    n_samples = values.shape[0]
    states = np.empty((n_samples, N_STATES))
    innovations = np.zeros((n_samples, at.size))
    jacobian = np.zeros((n_samples, at.size, N_FREE + N_STATES))
    Z0 = np.zeros((N_STATES, N_FREE + N_STATES))
    Z0[:, N_FREE:] = np.diag(X_SCALE)
    ok = filter_pass(step, StepFailed, np.arange(n_samples) * 0.01, [None] * n_samples, x_first.copy(), P0, Z0,
                     process_var, 1.0 / X_SCALE, np.full(N_STATES, -1e12), np.full(N_STATES, 1e12),
                     at.astype(np.int64), np.ascontiguousarray(values), sigma, seen.astype(np.uint8), POSITION,
                     STROKE_M, N_FREE, states, innovations, jacobian, gradients)
    return ok, states, innovations, jacobian


class _Ekf(ExtendedKalmanFilter):
    """filterpy's filter with the model's nonlinear prediction (its ``predict`` uses ``F`` for ``P`` only)."""

    def __init__(self, f, theta, **kw):
        super().__init__(**kw)
        self._f, self._theta = f, theta

    def predict_x(self, u=0):
        self.x = self._f(self.x, self._theta)


@pytest.mark.parametrize("nonlinear", [False, True])
@pytest.mark.parametrize("at", [np.array([POSITION]), np.array([POSITION, 2, 3]), np.array([2, 4])])
def test_filter_pass_agrees_with_filterpy(at, nonlinear):
    f, F, B = _model(5, nonlinear)
    theta = np.array([0.3, -0.2])
    sigma = np.where(at == POSITION, 5e-5, 300.0)
    values = _measurements(f, theta, at, sigma, 60, 11)
    seen = np.ones(values.shape, bool)
    seen[7, 0] = seen[20] = False                         # a value missing, a sample with none
    process_var = (X_SCALE * 1e-3) ** 2
    P0 = np.diag((X_SCALE * 0.01) ** 2)
    x_first = np.array([0.1005, 0.001, 3.02e5, 2.99e5, 0.002])
    ok, states, innovations, _ = _run_pass(f, F, B, theta, x_first, values, at, sigma, seen, process_var, P0)
    assert ok

    ekf = _Ekf(f, theta, dim_x=N_STATES, dim_z=at.size)
    ekf.x, ekf.P, ekf.Q = x_first.copy(), P0.copy(), np.diag(process_var)
    for k in range(values.shape[0]):
        if k > 0:
            ekf.F = F(ekf.x)
            ekf.predict()
        use = seen[k]
        if use.any():
            sub, sig = at[use], sigma[use]

            def readings(state, sub=sub, sig=sig):
                out = state[sub].astype(float).copy()
                out[sub == POSITION] = [expected_position_reading(state[POSITION], STROKE_M, s)[0]
                                        for s in sig[sub == POSITION]]
                return out

            def jac(state, sub=sub, sig=sig):
                H = np.zeros((sub.size, N_STATES))
                for i, j in enumerate(sub):
                    H[i, j] = expected_position_reading(state[POSITION], STROKE_M, sig[i])[1] if j == POSITION else 1.0
                return H

            ekf.R = np.diag(sig ** 2)
            ekf.dim_z = sub.size
            ekf.update(values[k, use], jac, readings)
            # the whitened innovations: L^-1 y with S = L L^T, the values in their order
            expected = np.linalg.solve(np.linalg.cholesky(ekf.S), ekf.y)
            np.testing.assert_allclose(innovations[k, use], expected, rtol=1e-6, atol=1e-9)
            assert np.sum(innovations[k, use] ** 2) == pytest.approx(ekf.mahalanobis ** 2, rel=1e-7)
        assert np.all(innovations[k, ~use] == 0.0)
        np.testing.assert_allclose(states[k], ekf.x, rtol=1e-9, atol=1e-12 * X_SCALE.max())


def test_innovations_jacobian_matches_finite_differences_on_a_linear_model():
    """On a linear model with linear readings the gain does not depend on the parameters or the first state, so
    the fixed-gain Jacobian is the exact derivative of the whitened innovations."""
    f, F, B = _model(9, False)
    at = np.array([2, 4])                                  # readings of states directly: linear
    sigma = np.array([300.0, 2e-3])
    theta = np.array([0.1, 0.4])
    values = _measurements(f, theta, at, sigma, 40, 3)
    seen = np.ones(values.shape, bool)
    process_var, P0 = (X_SCALE * 1e-3) ** 2, np.diag((X_SCALE * 0.01) ** 2)
    x_first = np.array([0.1, 0.0, 3e5, 3e5, 0.0])

    def whitened(theta_, x_first_):
        return _run_pass(f, F, B, theta_, x_first_, values, at, sigma, seen, process_var, P0)[2].ravel()

    _, _, _, jacobian = _run_pass(f, F, B, theta, x_first, values, at, sigma, seen, process_var, P0)
    jacobian = jacobian.reshape(-1, N_FREE + N_STATES)
    for j in range(N_FREE + N_STATES):
        h = 1e-6
        tp, tm, xp, xm = theta.copy(), theta.copy(), x_first.copy(), x_first.copy()
        if j < N_FREE:
            tp[j] += h
            tm[j] -= h
        else:                                              # the first state's columns are scaled
            xp[j - N_FREE] += h * X_SCALE[j - N_FREE]
            xm[j - N_FREE] -= h * X_SCALE[j - N_FREE]
        numeric = (whitened(tp, xp) - whitened(tm, xm)) / (2 * h)
        np.testing.assert_allclose(jacobian[:, j], numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())


def test_a_step_that_fails_keeps_the_state_and_says_so():
    f, F, B = _model(5, False)
    at, sigma = np.array([POSITION]), np.array([5e-5])
    values = _measurements(f, np.zeros(2), at, sigma, 10, 1)
    calls = []

    def step(t0, x, schedule, x_buffer, s_buffer):
        calls.append(t0)
        if len(calls) == 4:
            raise StepFailed
        x_buffer[1] = f(x, np.zeros(2))
        s_buffer[1, :, :N_FREE] = B
        s_buffer[1, :, N_FREE:] = F(x) * X_SCALE[None, :]

    states = np.empty((10, N_STATES))
    ok = filter_pass(step, StepFailed, np.arange(10) * 0.01, [None] * 10, values[0].repeat(5) * 0 + 0.1,
                     np.diag((X_SCALE * 0.01) ** 2), np.zeros((N_STATES, N_FREE + N_STATES)),
                     (X_SCALE * 1e-3) ** 2, 1.0 / X_SCALE, np.full(N_STATES, -1e12), np.full(N_STATES, 1e12),
                     at.astype(np.int64), values, sigma, np.ones((10, 1), np.uint8), POSITION, STROKE_M, N_FREE,
                     states, np.zeros((1, 1)), np.zeros((1, 1, N_FREE + N_STATES)), False)
    assert not ok and len(calls) == 9
    assert np.all(np.isfinite(states))


@pytest.mark.parametrize("position_m", [-3e-4, 0.0, 4e-5, 0.1, 0.19995, 0.2, 0.2003])
@pytest.mark.parametrize("noise_m", [5e-5, 2e-4, 0.0])
def test_compiled_sensor_reading_is_the_shooting_problems(position_m, noise_m):
    reading, slope = expected_reading(position_m, STROKE_M, noise_m)
    ref_reading, ref_slope = expected_position_reading(position_m, STROKE_M, noise_m)
    assert reading == pytest.approx(float(ref_reading), rel=1e-13, abs=1e-18)
    assert slope == pytest.approx(float(ref_slope), rel=1e-12, abs=1e-15)
