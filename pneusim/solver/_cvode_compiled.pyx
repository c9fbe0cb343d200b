# cython: language_level=3, boundscheck=False, wraparound=False
"""Compiled right-hand side and Jacobian for scikits.odes' CVODE.

CVODE calls ``evaluate`` of these classes through Cython's vtable, and
``evaluate`` calls the C code that CasADi generated for the model: no Python
runs per evaluation.  ``advance`` integrates to a stop time with the input held,
calling CVODE's C API on the solver object that scikits.odes set up.
"""

cimport numpy as np
import numpy as np
from libc.string cimport memcpy
from scikits.odes.sundials.cvode cimport CVODE, CV_RhsFunction, CV_JacRhsFunction
from scikits.odes.sundials.common_defs cimport DTYPE_t
from scikits.odes.sundials.c_sundials cimport N_Vector, sunrealtype
from scikits.odes.sundials.c_cvode cimport (CVode, CVodeSetStopTime, CVodeReInit, CV_NORMAL,
                                            CVodeGetNumSteps, CVodeGetNumRhsEvals,
                                            CVodeGetNumErrTestFails, CVodeGetNumNonlinSolvConvFails)
from scikits.odes.sundials.c_nvector_serial cimport N_VGetArrayPointer_Serial

ctypedef long long casadi_int
ctypedef int (*casadi_fn)(const double** arg, double** res, casadi_int* iw, double* w, int mem) noexcept nogil


cdef class CasadiKernel:
    """A CasADi-generated C function ``f(x, u, p) -> out`` called by pointer."""
    cdef casadi_fn fn
    cdef double[::1] w
    cdef casadi_int[::1] iw
    cdef double[::1] u
    cdef double[::1] p
    cdef const double* arg[3]
    cdef double* res[1]

    def __init__(self, size_t address, int n_iw, int n_w, double[::1] u, double[::1] p):
        self.fn = <casadi_fn> address
        self.iw = np.zeros(max(n_iw, 1), dtype=np.int64)
        self.w = np.zeros(max(n_w, 1), dtype=np.float64)
        self.u = u
        self.p = p

    cdef inline int call(self, const double* x, double* out) noexcept nogil:
        self.arg[0] = x
        self.arg[1] = &self.u[0]
        self.arg[2] = &self.p[0]
        self.res[0] = out
        return self.fn(self.arg, self.res, &self.iw[0], &self.w[0], 0)


cdef class CompiledRhs(CV_RhsFunction):
    """CVODE right-hand side ``ydot = f(y, u, p)``; ``u`` and ``p`` are shared buffers."""
    cdef CasadiKernel kernel

    def __init__(self, CasadiKernel kernel):
        self.kernel = kernel

    cpdef int evaluate(self, DTYPE_t t, np.ndarray[DTYPE_t, ndim=1] y, np.ndarray[DTYPE_t, ndim=1] ydot,
                       object userdata=None) except? -1:
        return self.kernel.call(<double*> y.data, <double*> ydot.data)


cdef class CompiledJac(CV_JacRhsFunction):
    """CVODE dense Jacobian ``J = df/dy``; CasADi writes column-major, CVODE's array is row-major."""
    cdef CasadiKernel kernel
    cdef double[::1] buffer
    cdef int n

    def __init__(self, CasadiKernel kernel, int n):
        self.kernel = kernel
        self.n = n
        self.buffer = np.zeros(n * n)

    cpdef int evaluate(self, DTYPE_t t, np.ndarray[DTYPE_t, ndim=1] y, np.ndarray[DTYPE_t, ndim=1] fy,
                       np.ndarray[DTYPE_t, ndim=2] J) except? -1:
        cdef int i, j, flag
        flag = self.kernel.call(<double*> y.data, &self.buffer[0])
        for j in range(self.n):
            for i in range(self.n):
                J[i, j] = self.buffer[j * self.n + i]
        return flag


def advance(CVODE solver, double t_stop, double[::1] y_out):
    """Integrate from the solver's current time to ``t_stop`` (input held). Returns the CVODE flag."""
    cdef sunrealtype t_reached = 0.0
    cdef int flag
    cdef void* mem = solver._cv_mem
    CVodeSetStopTime(mem, t_stop)
    flag = CVode(mem, t_stop, solver.y, &t_reached, CV_NORMAL)
    memcpy(&y_out[0], N_VGetArrayPointer_Serial(solver.y), y_out.shape[0] * sizeof(double))
    return flag, t_reached


def reinit(CVODE solver, double t0, double[::1] y0):
    """Restart CVODE at ``(t0, y0)`` keeping its memory and options (after a state jump)."""
    memcpy(N_VGetArrayPointer_Serial(solver.y), &y0[0], y0.shape[0] * sizeof(double))
    return CVodeReInit(solver._cv_mem, t0, solver.y)


def statistics(CVODE solver):
    """Counters of the run so far: steps, rhs evaluations, error-test and Newton failures."""
    cdef long int steps = 0, rhs = 0, etf = 0, ncf = 0
    CVodeGetNumSteps(solver._cv_mem, &steps)
    CVodeGetNumRhsEvals(solver._cv_mem, &rhs)
    CVodeGetNumErrTestFails(solver._cv_mem, &etf)
    CVodeGetNumNonlinSolvConvFails(solver._cv_mem, &ncf)
    return {"steps": steps, "rhs_evaluations": rhs, "error_test_failures": etf, "newton_failures": ncf}
