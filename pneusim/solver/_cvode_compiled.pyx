# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# distutils: extra_compile_args = -ffp-contract=off
"""Compiled right-hand side and Jacobian for scikits.odes' CVODE, and the sample loop in C.

* :class:`CompiledRhs` and :class:`CompiledJac` are scikits.odes callback
  classes (``CV_RhsFunction``, ``CV_JacRhsFunction``).  scikits.odes' CVODE
  calls their ``evaluate`` through Cython's vtable and ``evaluate`` calls the C
  code CasADi generated for the model: no Python runs per evaluation.
* :class:`Integrator` drives the CVODE memory that scikits.odes created and
  configured (BDF, Newton, SUNDIALS' serial N_Vector and dense linear solver):
  stop time, ``CVode``, ``CVodeReInit`` at input changes, counters.
* :class:`SampleLoop` runs :func:`pneusim.simulate.simulate`'s sample loop
  (sensors, proportional controller, zero-order hold, transport delay) in C on
  an :class:`Integrator`, for the built-in parts.

``-ffp-contract=off``: no fused multiply-adds, so that the loop computes the
same doubles as the Python code it replaces.
"""

from cpython.exc cimport PyErr_Occurred
from libc.stdlib cimport malloc, free
from libc.string cimport memcpy
from libc.math cimport nearbyint
cimport numpy as cnp
import numpy as np

from scikits.odes.sundials.cvode cimport CVODE, CV_RhsFunction, CV_JacRhsFunction, CV_ErrHandler
from scikits.odes.sundials.common_defs cimport DTYPE_t
from scikits.odes.sundials.c_sundials cimport N_Vector, sunrealtype
from scikits.odes.sundials.c_cvode cimport (CVode, CVodeSetStopTime, CVodeReInit, CV_NORMAL,
                                            CVodeGetNumSteps, CVodeGetNumRhsEvals, CVodeGetNumErrTestFails,
                                            CVodeGetNumNonlinSolvConvFails, CVodeGetNumJacEvals)
from scikits.odes.sundials.c_nvector_serial cimport N_VGetArrayPointer_Serial, N_VGetLength_Serial

cnp.import_array()

ctypedef long long casadi_int
ctypedef int (*casadi_fn)(const double** arg, double** res, casadi_int* iw, double* w, int mem) noexcept nogil


cdef class CasadiKernel:
    """A CasADi-generated C function ``f(x, u, p) -> out`` called by pointer.

    ``u`` and ``p`` are shared buffers: writing into them changes the model.
    """
    cdef casadi_fn fn
    cdef casadi_int* iw
    cdef double* w
    cdef const double* arg[3]
    cdef double* res[1]
    cdef object keep

    def __cinit__(self):
        self.iw = NULL
        self.w = NULL

    def __init__(self, compiled, double[::1] u, double[::1] p):
        self.keep = (compiled, u, p)   # raw pointers into these are held below
        self.fn = <casadi_fn> <size_t> compiled.address
        self.iw = <casadi_int*> malloc(max(compiled.n_iw, 1) * sizeof(casadi_int))
        self.w = <double*> malloc(max(compiled.n_w, 1) * sizeof(double))
        if self.iw == NULL or self.w == NULL:
            raise MemoryError()
        self.arg[1] = &u[0]
        self.arg[2] = &p[0]

    def __dealloc__(self):
        free(self.iw)
        free(self.w)

    cdef inline int call(self, const double* x, double* out) noexcept nogil:
        self.arg[0] = x
        self.res[0] = out
        return self.fn(self.arg, self.res, self.iw, self.w, 0)


cdef class CompiledRhs(CV_RhsFunction):
    """CVODE right-hand side ``ydot = f(y, u, p)``.

    The arrays are declared without a buffer type: scikits.odes hands over its
    own contiguous float64 work arrays, and reading their data pointer skips
    two buffer acquisitions per evaluation.
    """
    cdef CasadiKernel kernel

    def __init__(self, CasadiKernel kernel):
        self.kernel = kernel

    cpdef int evaluate(self, DTYPE_t t, cnp.ndarray y, cnp.ndarray ydot, object userdata=None) except? -1:
        return self.kernel.call(<double*> cnp.PyArray_DATA(y), <double*> cnp.PyArray_DATA(ydot))


cdef class CompiledJac(CV_JacRhsFunction):
    """CVODE dense Jacobian ``J = df/dy``.

    CasADi writes column-major, scikits.odes' ``J`` is a C-ordered (row-major)
    array that it copies into SUNDIALS' dense matrix: transposed on the way.
    """
    cdef CasadiKernel kernel
    cdef double* buffer
    cdef int n

    def __cinit__(self):
        self.buffer = NULL

    def __init__(self, CasadiKernel kernel, int n):
        self.kernel = kernel
        self.n = n
        self.buffer = <double*> malloc(n * n * sizeof(double))
        if self.buffer == NULL:
            raise MemoryError()

    def __dealloc__(self):
        free(self.buffer)

    cpdef int evaluate(self, DTYPE_t t, cnp.ndarray y, cnp.ndarray fy, cnp.ndarray J) except? -1:
        cdef int i, j, flag
        cdef double* out = <double*> cnp.PyArray_DATA(J)
        if not cnp.PyArray_IS_C_CONTIGUOUS(J) or cnp.PyArray_SIZE(J) != self.n * self.n:
            raise ValueError("expected a C-ordered n x n Jacobian array")
        flag = self.kernel.call(<double*> cnp.PyArray_DATA(y), self.buffer)
        for j in range(self.n):
            for i in range(self.n):
                out[i * self.n + j] = self.buffer[j * self.n + i]
        return flag


cdef class ErrorText(CV_ErrHandler):
    """scikits.odes error handler keeping CVODE's last message (instead of printing it)."""
    cdef public str message

    def __init__(self):
        self.message = ""

    cpdef evaluate(self, int error_code, bytes module, bytes function, bytes msg, object user_data=None):
        self.message = msg.decode("utf-8", "replace")


cdef int _raise_pending() except -1:
    # an exception raised inside a callback is left set by scikits.odes' C wrappers: propagate it
    if PyErr_Occurred() != NULL:
        return -1
    return 0


cdef class Integrator:
    """Drives the CVODE memory of a scikits.odes ``CVODE`` solver from C.

    Parameters
    ----------
    solver : scikits.odes.sundials.cvode.CVODE
        Configured with :class:`CompiledRhs` / :class:`CompiledJac`; initialised by :meth:`reset`.
    u : ndarray (1,)
        The input buffer the kernels read.
    errors : ErrorText
        The error handler given to ``solver``.

    ``CVode`` runs with the GIL held: scikits.odes' C wrappers around our
    callbacks handle Python objects.  The state lives in the solver's own
    output vector (``solver.y``), read and written in place.
    """
    cdef CVODE solver
    cdef void* mem
    cdef N_Vector y
    cdef double* u_in            # the input buffer the kernels read
    cdef readonly int n
    cdef object keep
    cdef readonly ErrorText errors
    cdef readonly bint initialized
    cdef long totals[5]

    def __init__(self, CVODE solver, double[::1] u, ErrorText errors, int n):
        cdef int i
        self.solver = solver
        self.u_in = &u[0]
        self.n = n
        self.errors = errors
        self.keep = [u]
        self.initialized = False
        for i in range(5):
            self.totals[i] = 0

    @property
    def u(self):
        """The input held now."""
        return self.u_in[0]

    def state(self):
        """A copy of CVODE's current solution vector."""
        if not self.initialized:
            raise RuntimeError("reset the integrator first")
        out = np.empty(self.n)
        memcpy(<double*> cnp.PyArray_DATA(out), N_VGetArrayPointer_Serial(self.y), self.n * sizeof(double))
        return out

    def reset(self, double t0, double[::1] x0, double u):
        """Start again at ``(t0, x0)`` with input ``u``; the counters start from zero."""
        cdef int i
        if x0.shape[0] != self.n:
            raise ValueError(f"{self.n} states expected, got {x0.shape[0]}")
        self.u_in[0] = u
        if not self.initialized:
            # scikits.odes creates CVODE here and points its y0 vector at this array: keep it alive
            x_init = np.array(x0, dtype=float)
            self.keep.append(x_init)
            self.solver.init_step(t0, x_init)
            self.mem = self.solver._cv_mem
            self.y = self.solver.y   # stays while the solver lives: init_step is not called again
            if self.mem == NULL or self.y == NULL or N_VGetLength_Serial(self.y) != self.n:
                raise RuntimeError("scikits.odes did not set up CVODE as expected")
        memcpy(N_VGetArrayPointer_Serial(self.y), &x0[0], self.n * sizeof(double))
        flag = CVodeReInit(self.mem, t0, self.y)
        if flag < 0:
            raise RuntimeError(f"CVodeReInit failed with flag {flag}")
        for i in range(5):
            self.totals[i] = 0
        self.initialized = True

    cdef void _bank(self) noexcept:
        # CVodeReInit zeroes CVODE's counters; keep the run's totals here
        cdef long v = 0
        CVodeGetNumSteps(self.mem, &v); self.totals[0] += v
        CVodeGetNumRhsEvals(self.mem, &v); self.totals[1] += v
        CVodeGetNumErrTestFails(self.mem, &v); self.totals[2] += v
        CVodeGetNumNonlinSolvConvFails(self.mem, &v); self.totals[3] += v
        CVodeGetNumJacEvals(self.mem, &v); self.totals[4] += v

    cdef int _advance(self, double t_now, double t_stop, double u, sunrealtype* t_reached) noexcept:
        cdef int flag
        if u != self.u_in[0]:
            # The input jumps: restart the BDF history at t_now so that no step is predicted
            # from the solution under the old input (which fails with stiff spool dynamics).
            self.u_in[0] = u
            self._bank()
            flag = CVodeReInit(self.mem, t_now, self.y)
            if flag < 0:
                return flag
        CVodeSetStopTime(self.mem, t_stop)
        return CVode(self.mem, t_stop, self.y, t_reached, CV_NORMAL)

    def advance(self, double t_now, double t_stop, double u):
        """Integrate from ``t_now`` (the time of the state) to ``t_stop`` with ``u`` held.

        Returns ``(flag, t_reached, message)``; :meth:`state` gives the state.
        """
        cdef sunrealtype t_reached = t_now
        cdef int flag
        if not self.initialized:
            raise RuntimeError("reset the integrator first")
        self.errors.message = ""
        flag = self._advance(t_now, t_stop, u, &t_reached)
        _raise_pending()
        return flag, t_reached, (self.errors.message if flag < 0 else "")

    def statistics(self):
        """Counters since :meth:`reset`: steps, rhs and Jacobian evaluations, error-test and Newton failures."""
        cdef long v[5]
        keys = ("steps", "rhs_evaluations", "error_test_failures", "newton_failures", "jacobian_evaluations")
        if not self.initialized:
            return dict.fromkeys(keys, 0)
        CVodeGetNumSteps(self.mem, &v[0])
        CVodeGetNumRhsEvals(self.mem, &v[1])
        CVodeGetNumErrTestFails(self.mem, &v[2])
        CVodeGetNumNonlinSolvConvFails(self.mem, &v[3])
        CVodeGetNumJacEvals(self.mem, &v[4])
        return {k: self.totals[i] + v[i] for i, k in enumerate(keys)}


cdef class SampleLoop:
    """The sample loop of :func:`pneusim.simulate.simulate` in C, for the built-in parts.

    Per sample, exactly as the Python loop with :class:`~pneusim.plant.SimulatedPlant`,
    :class:`~pneusim.sensors.Sensors` and :class:`~pneusim.controller.ProportionalController`:
    measure (noise, then converter), command (proportional law, clipped; or
    the open-loop signal), record, hold the command for one sample (through
    the transport delay, if any).  Same operations in the same order on the
    same doubles, and the same CVODE calls, so the recordings are the same to the last bit.
    """
    cdef Integrator integ
    cdef readonly long k                 # samples stepped since the plant's reset
    cdef readonly double t               # the integrator's time
    cdef readonly double seen_V          # the command the (delayed) valve sees
    cdef double t0, ts, delay, eps
    cdef bint closed
    cdef double kp, u0, u_min, u_max
    cdef double pos_std, pos_quantum, stroke, p_std, p_quantum
    cdef double[::1] pend_t
    cdef double[::1] pend_v
    cdef long pend_head, pend_count

    def __init__(self, Integrator integ, double t0, long k, double t, double sample_time, double delay,
                 double seen_V, pending, controller, double position_std, double position_quantum,
                 double stroke, double pressure_std, double pressure_quantum):
        if not integ.initialized:
            raise RuntimeError("reset the integrator first")
        self.integ = integ
        self.t0, self.k, self.t, self.ts, self.delay = t0, k, t, sample_time, delay
        self.eps = 1e-9 * sample_time
        self.seen_V = seen_V
        cap = len(pending) + int(delay / sample_time) + 4 if delay > 0 else 1
        self.pend_t = np.zeros(cap)
        self.pend_v = np.zeros(cap)
        self.pend_head, self.pend_count = 0, 0
        for ts_, v in pending:
            self._push(ts_, v)
        self.closed = controller is not None
        if self.closed:
            self.kp, self.u0 = controller.kp_V_per_m, controller.u0_V
            self.u_min, self.u_max = controller.u_min_V, controller.u_max_V
        self.pos_std, self.pos_quantum, self.stroke = position_std, position_quantum, stroke
        self.p_std, self.p_quantum = pressure_std, pressure_quantum

    @property
    def normals_per_sample(self):
        return (1 if self.pos_std > 0 else 0) + (2 if self.p_std > 0 else 0)

    @property
    def pending(self):
        cdef long i, cap = self.pend_t.shape[0]
        return [(self.pend_t[(self.pend_head + i) % cap], self.pend_v[(self.pend_head + i) % cap])
                for i in range(self.pend_count)]

    cdef void _push(self, double t_switch, double value) noexcept nogil:
        cdef long cap = self.pend_t.shape[0]
        cdef long i = (self.pend_head + self.pend_count) % cap
        self.pend_t[i] = t_switch
        self.pend_v[i] = value
        self.pend_count += 1

    cdef inline double _pressure(self, double true_Pa, const double* z, long* iz) noexcept nogil:
        cdef double y = true_Pa + (self.p_std * z[iz[0]] if self.p_std > 0 else 0.0)
        if self.p_std > 0:
            iz[0] += 1
        if self.p_quantum > 0:
            y = nearbyint(y / self.p_quantum) * self.p_quantum
        return y

    cdef int _step(self, double u, sunrealtype* t_reached) noexcept:
        # SimulatedPlant.step
        cdef double t_now = self.t0 + self.k * self.ts
        cdef double t_end = self.t0 + (self.k + 1) * self.ts
        cdef double t, t_switch, value
        cdef long cap = self.pend_t.shape[0]
        cdef int flag
        if self.delay <= 0.0:
            flag = self.integ._advance(self.t, t_end, u, t_reached)
            if flag < 0:
                return flag
            self.t = t_end
        else:
            self._push(t_now + self.delay, u)
            t = t_now
            while self.pend_count > 0 and self.pend_t[self.pend_head] < t_end - self.eps:
                t_switch = self.pend_t[self.pend_head]
                value = self.pend_v[self.pend_head]
                self.pend_head = (self.pend_head + 1) % cap
                self.pend_count -= 1
                if t_switch > t + self.eps:
                    flag = self.integ._advance(self.t, t_switch, self.seen_V, t_reached)
                    if flag < 0:
                        return flag
                    self.t = t_switch
                    t = t_switch
                self.seen_V = value
            flag = self.integ._advance(self.t, t_end, self.seen_V, t_reached)
            if flag < 0:
                return flag
            self.t = t_end
        self.k += 1
        return 0

    def run(self, long k_from, long k_to, long n, const double[::1] signal, const double[::1] normals,
            double[::1] positions, double[::1] commands, double[::1] pressure_a, double[::1] pressure_b,
            double[:, ::1] states):
        """Samples ``k_from .. k_to - 1`` of :func:`simulate`'s loop (``k < 0``: warm-up, not recorded).

        ``normals`` holds the sensors' next standard normal draws, ``normals_per_sample`` a sample.
        Returns ``(flag, t_reached, message)``; flag < 0 is CVODE's failure.
        """
        cdef long kk, i, iz = 0
        cdef int flag = 0
        cdef int nx = states.shape[1]
        # CVODE's own solution vector: read in place (CVode writes the state at t_stop into it)
        cdef double* x = <double*> N_VGetArrayPointer_Serial(self.integ.y)
        cdef double y, ref, u, p_a, p_b
        cdef sunrealtype t_reached = self.t
        cdef long last = min(k_to, n) - 1
        if (last >= 0 and (signal.shape[0] <= last or positions.shape[0] <= last or commands.shape[0] <= last
                           or pressure_a.shape[0] <= last or pressure_b.shape[0] <= last
                           or states.shape[0] <= last)) or nx != self.integ.n:
            raise ValueError("signal or output arrays too short for the samples asked for")
        if normals.shape[0] < (k_to - k_from) * self.normals_per_sample:
            raise ValueError(f"{(k_to - k_from) * self.normals_per_sample} noise draws needed, "
                             f"{normals.shape[0]} given")
        self.integ.errors.message = ""
        for kk in range(k_from, k_to):
            # Sensors.position, then the two pressures
            y = x[0] + (self.pos_std * normals[iz] if self.pos_std > 0 else 0.0)
            if self.pos_std > 0:
                iz += 1
            if self.pos_quantum > 0:
                if 0.0 > y:
                    y = 0.0
                if self.stroke < y:
                    y = self.stroke
                y = nearbyint(y / self.pos_quantum) * self.pos_quantum
            p_a = self._pressure(x[2], &normals[0], &iz)
            p_b = self._pressure(x[3], &normals[0], &iz)
            ref = signal[kk if kk > 0 else 0]
            if self.closed:
                # ProportionalController.command: min(max(u, u_min), u_max) as Python does it
                u = self.u0 + self.kp * (ref - y)
                if self.u_min > u:
                    u = self.u_min
                if self.u_max < u:
                    u = self.u_max
            else:
                u = ref
            if kk >= 0:
                positions[kk] = y
                commands[kk] = u
                pressure_a[kk] = p_a
                pressure_b[kk] = p_b
                for i in range(nx):
                    states[kk, i] = x[i]
                if kk == n - 1:
                    break
            flag = self._step(u, &t_reached)
            if flag < 0:
                break
        _raise_pending()
        return flag, t_reached, (self.integ.errors.message if flag < 0 else "")
