# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
# distutils: extra_compile_args = -ffp-contract=off
"""Paper 1's RLS (eq. 8) and its h-step predictions in C, for a 1 ms loop.

:class:`RlsKernel` holds everything :class:`pneusim.online.PaperRLS`
needs per sample in C arrays: ``theta`` (2n), ``P`` (2n x 2n, row-major), the
last ``n + hmax`` outputs and inputs and the last ``hmax`` values of ``theta``
(ring buffers), so that one sample of an order-5 estimator with 1/5/10-step
predictions costs about a microsecond instead of the ~40 us that small numpy
arrays cost in call overhead.  The arithmetic is the numpy reference's, written
out: ``Ppsi = P psi``, ``denom = lambda + psi' Ppsi``, ``theta += Ppsi (y -
psi' theta) / denom``, ``P = (P - Ppsi Ppsi' / denom) / lambda``, every dot
product summed left to right: the same doubles as eq. 8 written in plain Python
floats (``tests/pneusim/online/test_rls.py``).  numpy's BLAS sums in another order,
which RLS on paper 1's data amplifies to ~1e-10 of theta (as much as a one-ulp
change of the data does).

``-ffp-contract=off``: no fused multiply-adds, so the same doubles on every
x86-64 build.
"""

from libc.stdlib cimport malloc, free
from libc.math cimport NAN

import numpy as np


cdef class RlsKernel:
    """State of one online ARMA estimator of order ``n`` with horizons ``horizons`` (see the module docstring).

    Parameters
    ----------
    order : int
    forgetting : float
    initial_covariance : float
        ``c`` of ``P(0) = c I``.
    horizons : sequence of int
        Prediction steps, each >= 1.
    """

    cdef int n, m, hmax, nh, len_hist
    cdef double lam
    cdef double *P
    cdef double *theta
    cdef double *ppsi
    cdef double *psi
    cdef double *yh            # ring of the last len_hist outputs, yh[(pos_y - 1 - i) % len] = y(k-1-i)
    cdef double *uh            # ring of the last len_hist inputs
    cdef double *th            # ring of the last hmax thetas (hmax rows of m)
    cdef double *hist          # scratch of n + hmax values for the h-step iteration
    cdef int *hz
    cdef int pos_y, pos_u, pos_th
    cdef public long k         # outputs taken
    cdef public long n_thetas  # thetas stored (min with hmax is what is available)
    cdef double[:, ::1] _log

    def __cinit__(self, int order, double forgetting, double initial_covariance, horizons):
        cdef int i
        hs = [int(h) for h in horizons]
        if order < 1 or not hs or min(hs) < 1:
            raise ValueError("order >= 1 and horizons >= 1 expected")
        self.n, self.m = order, 2 * order
        self.lam = forgetting
        self.nh = len(hs)
        self.hmax = max(hs)
        self.len_hist = self.n + self.hmax
        self.P = <double *> malloc(self.m * self.m * sizeof(double))
        self.theta = <double *> malloc(self.m * sizeof(double))
        self.ppsi = <double *> malloc(self.m * sizeof(double))
        self.psi = <double *> malloc(self.m * sizeof(double))
        self.yh = <double *> malloc(self.len_hist * sizeof(double))
        self.uh = <double *> malloc(self.len_hist * sizeof(double))
        self.th = <double *> malloc(self.hmax * self.m * sizeof(double))
        self.hist = <double *> malloc((self.n + self.hmax) * sizeof(double))
        self.hz = <int *> malloc(self.nh * sizeof(int))
        if (self.P == NULL or self.theta == NULL or self.ppsi == NULL or self.psi == NULL or self.yh == NULL
                or self.uh == NULL or self.th == NULL or self.hist == NULL or self.hz == NULL):
            raise MemoryError()
        for i in range(self.nh):
            self.hz[i] = hs[i]
        for i in range(self.m * self.m):
            self.P[i] = 0.0
        for i in range(self.m):
            self.P[i * self.m + i] = initial_covariance
            self.theta[i] = 0.0
        for i in range(self.len_hist):
            self.yh[i] = 0.0
            self.uh[i] = 0.0
        for i in range(self.hmax * self.m):
            self.th[i] = 0.0
        self.pos_y = self.pos_u = self.pos_th = 0
        self.k = self.n_thetas = 0

    def __dealloc__(self):
        free(self.P); free(self.theta); free(self.ppsi); free(self.psi)
        free(self.yh); free(self.uh); free(self.th); free(self.hist); free(self.hz)

    cdef inline double _y(self, int back):
        """y(k-back), back >= 1 (zeros before the first sample)."""
        return self.yh[(self.pos_y - back + self.len_hist) % self.len_hist]

    cdef inline double _u(self, int back):
        return self.uh[(self.pos_u - back + self.len_hist) % self.len_hist]

    cdef double _predict(self, int h):
        """yhat(k | k-h) from theta(k-h), y up to k-h and u up to k-1 (NaN until available)."""
        cdef int n = self.n, j, i, nhist
        cdef double acc
        cdef double *a
        cdef double *b
        if h > self.n_thetas or h > self.hmax or self.k < n + h:
            return NAN
        a = self.th + ((self.pos_th - h + self.hmax) % self.hmax) * self.m     # theta(k-h)
        b = a + n
        # hist[0..n-1] = y(k-h-n+1) .. y(k-h), oldest first; the predictions are appended
        for i in range(n):
            self.hist[i] = self._y(h + n - 1 - i)
        nhist = n
        for j in range(1, h + 1):
            acc = 0.0
            for i in range(n):
                # u(k-h+j-1-i), i.e. (h - j + 1 + i) samples back from k
                acc += b[i] * self._u(h - j + 1 + i) - a[i] * self.hist[nhist - 1 - i]
            self.hist[nhist] = acc
            nhist += 1
        return self.hist[nhist - 1]

    def predictions(self):
        """``yhat(k | k-h)`` for every horizon (tuple, in the order given), before ``y(k)`` is taken."""
        cdef int i
        return tuple([self._predict(self.hz[i]) for i in range(self.nh)])

    cdef void _rls(self, double y):
        cdef int n = self.n, m = self.m, i, j
        cdef double denom, e, acc, inv_lam = 0.0
        cdef double *row
        for i in range(n):
            self.psi[i] = -self._y(i + 1)
            self.psi[n + i] = self._u(i + 1)
        for i in range(m):
            row = self.P + i * m
            acc = 0.0
            for j in range(m):
                acc += row[j] * self.psi[j]
            self.ppsi[i] = acc
        denom = 0.0
        e = 0.0
        for i in range(m):
            denom += self.psi[i] * self.ppsi[i]
            e += self.psi[i] * self.theta[i]
        denom = self.lam + denom
        e = (y - e) / denom
        for i in range(m):
            self.theta[i] = self.theta[i] + self.ppsi[i] * e
        for i in range(m):
            row = self.P + i * m
            for j in range(m):
                row[j] = (row[j] - self.ppsi[i] * self.ppsi[j] / denom) / self.lam

    cdef void _push_theta(self):
        cdef int i
        cdef double *dst = self.th + self.pos_th * self.m
        for i in range(self.m):
            dst[i] = self.theta[i]
        self.pos_th = (self.pos_th + 1) % self.hmax
        self.n_thetas += 1

    cdef void _push_y(self, double y):
        self.yh[self.pos_y] = y
        self.pos_y = (self.pos_y + 1) % self.len_hist
        self.k += 1

    def update(self, double y):
        """Predict (tuple over the horizons), then take ``y(k)``: eq. 8 and the bookkeeping."""
        preds = self.predictions()
        self._rls(y)
        self._push_y(y)
        self._push_theta()
        return preds

    def take_output(self, double y):
        """Predict, then store ``y(k)`` without an RLS update (another engine updates theta)."""
        preds = self.predictions()
        self._push_y(y)
        return preds

    def add_input(self, double u):
        """Store ``u(k)``, applied after ``y(k)``."""
        self.uh[self.pos_u] = u
        self.pos_u = (self.pos_u + 1) % self.len_hist

    def set_theta(self, theta):
        """Set theta (another engine's) and store it as ``theta(k)`` for the predictions."""
        cdef int i
        cdef double[::1] t = np.ascontiguousarray(theta, dtype=float)
        if t.shape[0] != self.m:
            raise ValueError(f"theta of {self.m} values expected")
        for i in range(self.m):
            self.theta[i] = t[i]
        self._push_theta()

    def theta_copy(self):
        """``theta`` as a new ndarray (2n,)."""
        cdef int i
        out = np.empty(self.m)
        cdef double[::1] o = out
        for i in range(self.m):
            o[i] = self.theta[i]
        return out

    def copy_theta_into(self, double[::1] out):
        """Write ``theta`` into ``out`` (2n,), no allocation."""
        cdef int i
        for i in range(self.m):
            out[i] = self.theta[i]

    def set_theta_log(self, double[:, ::1] log):
        """Keep ``log`` (n_rows, 2n): :meth:`log_theta` writes ``theta`` into its rows."""
        if log.shape[1] != self.m:
            raise ValueError(f"a theta log of {self.m} columns expected")
        self._log = log

    def log_theta(self, Py_ssize_t row):
        """Write ``theta`` into row ``row`` of the log given to :meth:`set_theta_log` (no allocation)."""
        cdef int i
        if self._log is None:
            raise ValueError("no theta log set")
        if row < 0 or row >= self._log.shape[0]:
            raise IndexError(f"theta log row {row} out of range")
        for i in range(self.m):
            self._log[row, i] = self.theta[i]

    def P_copy(self):
        """``P`` as a new ndarray (2n, 2n)."""
        cdef int i
        out = np.empty((self.m, self.m))
        cdef double[::1] o = out.reshape(-1)
        for i in range(self.m * self.m):
            o[i] = self.P[i]
        return out
