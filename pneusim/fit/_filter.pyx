# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
# distutils: extra_compile_args = -ffp-contract=off
"""The tracking filter's pass over a window in C (:func:`pneusim.fit.tracking.run_filter`'s loop).

Each sample: one step of the fit's integrator (a Python callable, the sensitivity simulator's
``step_into``), then the extended Kalman filter's prediction ``P = F P F^T + Q`` (``F`` the step's state
sensitivities) and the sensitivities' ``Z = F Z + S_theta``, then its update by each measured value in
turn, linearised at the predicted state, in Joseph form; then the state clipped to its bounds.

Why in C: the matrices are 4 x 4 to 8 x 20, where NumPy's call overhead costs more than the sample's
integration, and its small products go through OpenBLAS, whose kernels (Haswell's fused multiply-adds,
Sandybridge's without) round differently: on a chaotic recording the filter's landing then depended on
the processor.  Here every sum runs left to right without fused multiply-adds
(``-ffp-contract=off``): the same doubles on every x86-64 build.
"""

from libc.math cimport erfc, exp, sqrt, isfinite, NAN, M_SQRT1_2
from libc.stdlib cimport malloc, free

import numpy as np

cdef double INV_SQRT_2PI = 0.3989422804014327


cdef inline double _ndtr(double z) nogil:
    """The standard normal's distribution function."""
    return 0.5 * erfc(-z * M_SQRT1_2)


cdef inline double _g(double z) nogil:
    """E[max(Z + z, 0)] for a standard normal Z: z Phi(z) + phi(z)."""
    return z * _ndtr(z) + exp(-0.5 * z * z) * INV_SQRT_2PI


cdef void _expected_reading(double x, double stroke, double s, double* reading, double* slope) nogil:
    """The saturating sensor's mean reading and its slope (:func:`pneusim.fit.shooting.expected_position_reading`)."""
    cdef double z_high, z_low
    if s <= 0.0:
        reading[0] = 0.0 if x < 0.0 else (stroke if x > stroke else x)
        slope[0] = 1.0 if (x > 0.0 and x < stroke) else 0.0
        return
    z_high = (x - stroke) / s
    z_low = -x / s
    reading[0] = x - s * _g(z_high) + s * _g(z_low)
    slope[0] = 1.0 - _ndtr(z_high) - _ndtr(z_low)


def expected_reading(double x, double stroke, double s):
    """``(reading, slope)`` as the filter computes them (for the tests' comparison with the Python function)."""
    cdef double r, sl
    _expected_reading(x, stroke, s, &r, &sl)
    return r, sl


def filter_pass(step, failure, const double[::1] time_s, list schedules, double[::1] x_first, double[:, ::1] P0,
                double[:, ::1] Z0, const double[::1] process_var, const double[::1] inverse_scale,
                const double[::1] x_lo, const double[::1] x_hi, const long[::1] at, const double[:, ::1] values,
                const double[::1] sigma, const unsigned char[:, ::1] seen, long position_index, double stroke_m,
                int n_free, double[:, ::1] states, double[:, ::1] innovations, double[:, :, ::1] jacobian,
                bint gradients, bint stop_at_failure=False):
    """One pass of the filter over ``time_s.shape[0]`` samples; returns whether every step integrated.

    ``step(t0, x, schedule, x_buffer, s_buffer)`` integrates one sample from ``x`` (raising ``failure`` where it
    cannot), writing the new state to ``x_buffer[1]`` and its sensitivities ``(n, n_free + n)`` to
    ``s_buffer[1]``, whose state columns are scaled (``inverse_scale``, ``1 / x_scale``, undoes it).  ``P0``,
    ``Z0``: the first state's covariance and sensitivities (``Z0`` unused without ``gradients``);
    ``process_var``: the process noise variance per state.  ``at``, ``values`` (N, m),
    ``sigma``, ``seen`` (N, m): the measured states, their values, noise std and where they exist.  Writes the
    filtered states to ``states`` (N, n); with ``gradients`` the whitened innovations to ``innovations`` (N, m)
    and their derivative to ``jacobian`` (N, m, n_free + n), zero where a value is missing.  A sample that
    cannot be integrated keeps the predicted state as it was; with ``stop_at_failure`` the pass ends there
    instead, nothing written for that sample or after it.
    """
    cdef Py_ssize_t N = time_s.shape[0], n = x_first.shape[0], m = at.shape[0]
    cdef Py_ssize_t c = n_free + n
    cdef Py_ssize_t k, i, j, l, o, a
    cdef bint ok = True, finite
    cdef double acc, s, r2, S, root, y, reading, slope
    x_arr = np.array(x_first, dtype=float)
    cdef double[::1] x = x_arr
    x_buffer = np.empty((2, n))
    s_buffer = np.empty((2, n, c))
    cdef double[:, ::1] xb = x_buffer
    cdef double[:, :, ::1] sb = s_buffer
    cdef double* P = <double*> malloc(n * n * sizeof(double))
    cdef double* T = <double*> malloc(n * n * sizeof(double))
    cdef double* F = <double*> malloc(n * n * sizeof(double))
    cdef double* Z = <double*> malloc(n * c * sizeof(double))
    cdef double* Zt = <double*> malloc(n * c * sizeof(double))
    cdef double* K = <double*> malloc(n * sizeof(double))
    cdef double* predicted = <double*> malloc(n * sizeof(double))
    cdef double* HZ = <double*> malloc(c * sizeof(double))
    if not (P and T and F and Z and Zt and K and predicted and HZ):
        free(P); free(T); free(F); free(Z); free(Zt); free(K); free(predicted); free(HZ)
        raise MemoryError()
    try:
        for i in range(n):
            for j in range(n):
                P[i * n + j] = P0[i, j]
            for j in range(c):
                Z[i * c + j] = Z0[i, j] if gradients else 0.0
        for k in range(N):
            if k > 0:
                for i in range(n):
                    xb[1, i] = NAN
                try:
                    step(time_s[k - 1], x_arr, schedules[k], x_buffer, s_buffer)
                except failure:
                    pass
                finite = True
                for i in range(n):
                    if not isfinite(xb[1, i]):
                        finite = False
                if finite:
                    # F = d x_k / d x_{k-1}; the simulator's state columns are scaled
                    for i in range(n):
                        x[i] = xb[1, i]
                        for j in range(n):
                            F[i * n + j] = sb[1, i, n_free + j] * inverse_scale[j]
                    # P = F P F^T + Q
                    for i in range(n):
                        for j in range(n):
                            acc = 0.0
                            for l in range(n):
                                acc = acc + F[i * n + l] * P[l * n + j]
                            T[i * n + j] = acc
                    for i in range(n):
                        for j in range(n):
                            acc = 0.0
                            for l in range(n):
                                acc = acc + T[i * n + l] * F[j * n + l]
                            P[i * n + j] = acc + (process_var[i] if i == j else 0.0)
                    if gradients:
                        # Z = F Z, plus the step's own parameter sensitivities
                        for i in range(n):
                            for j in range(c):
                                acc = 0.0
                                for l in range(n):
                                    acc = acc + F[i * n + l] * Z[l * c + j]
                                Zt[i * c + j] = acc + (sb[1, i, j] if j < n_free else 0.0)
                        for i in range(n * c):
                            Z[i] = Zt[i]
                else:
                    ok = False
                    if stop_at_failure:
                        break
            # the update, one measured value at a time, each linearised at the predicted state
            for i in range(n):
                predicted[i] = x[i]
            for o in range(m):
                if not seen[k, o]:
                    continue
                a = at[o]
                if a == position_index:
                    _expected_reading(predicted[a], stroke_m, sigma[o], &reading, &slope)
                else:
                    reading, slope = predicted[a], 1.0
                s = slope
                r2 = sigma[o] * sigma[o]
                for i in range(n):
                    K[i] = P[i * n + a] * s                  # P h^T
                S = K[a] * s + r2                            # h P h^T + r
                root = sqrt(S)
                for i in range(n):
                    K[i] = K[i] / S
                y = values[k, o] - reading - s * (x[a] - predicted[a])
                for i in range(n):
                    x[i] = x[i] + K[i] * y
                # Joseph form: T = (I - K h) P, then P = T (I - K h)^T + r K K^T
                for i in range(n):
                    for j in range(n):
                        T[i * n + j] = P[i * n + j] - K[i] * s * P[a * n + j]
                for i in range(n):
                    for j in range(n):
                        P[i * n + j] = T[i * n + j] - T[i * n + a] * s * K[j] + r2 * K[i] * K[j]
                if gradients:
                    innovations[k, o] = y / root
                    for j in range(c):
                        HZ[j] = Z[a * c + j] * s
                        jacobian[k, o, j] = -HZ[j] / root
                    for i in range(n):
                        for j in range(c):
                            Z[i * c + j] = Z[i * c + j] - K[i] * HZ[j]
            for i in range(n):
                if x[i] < x_lo[i]:
                    x[i] = x_lo[i]
                elif x[i] > x_hi[i]:
                    x[i] = x_hi[i]
                states[k, i] = x[i]
    finally:
        free(P); free(T); free(F); free(Z); free(Zt); free(K); free(predicted); free(HZ)
    return ok
