# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# distutils: extra_compile_args = -ffp-contract=off
"""SUNDIALS CVODE driven from C on the CasADi-generated model, and the sample loop in C.

* :class:`Integrator` owns one CVODE memory (BDF, Newton, SUNDIALS' serial
  N_Vector and dense matrix, and a dense direct linear solver, with the per-step
  vector operations of ``small_vector.h`` and the dense LU and matrix operations of
  ``small_dense.h``: SUNDIALS' arithmetic in one call each, unrolled for small
  state counts, the same doubles at twice the speed), created and driven
  through the SUNDIALS C functions that ``scikits.odes`` declares (its
  ``c_cvode``, ``c_sundials``, ``c_nvector_serial``, ``c_sunmatrix`` and
  ``c_sunlinsol`` Cython declarations) and linked against the SUNDIALS library
  ``scikits.odes`` is built on.  Its right-hand side and Jacobian are C
  callbacks that call the C code CasADi generated for the model, reading and
  writing SUNDIALS' own vectors and dense (column-major, like CasADi's) matrix:
  no Python and no copy per evaluation.
* The held input jumps at sample boundaries, so the solution has a kink there:
  the integration stops exactly at the boundary (``CVodeSetStopTime``) and, by
  default, restarts the BDF history there (``CVodeReInit``, order 1).  Keeping
  the history across the kink instead (only the held input changing) was
  measured: fewer steps on paper 1, more on paper 2, and 2-5x the position error
  at the same tolerance, so it is not the default (see :data:`POLICIES` and
  ``benchmarks/test_bench_simulator.py``, which prints steps and evaluations per
  sample of every policy).
* :class:`SampleLoop` runs :func:`pneusim.simulate.simulate`'s sample loop
  (sensors, proportional controller, zero-order hold, transport delay) in C on
  an :class:`Integrator`, for the built-in parts; the sample-by-sample plant
  calls the same :meth:`Integrator.advance`.

``-ffp-contract=off``: no fused multiply-adds, so that the loop computes the
same doubles as the Python code it replaces.
"""

from libc.stdlib cimport malloc, free
from libc.string cimport memcpy
from libc.math cimport nearbyint
cimport numpy as cnp
import numpy as np

from scikits.odes.sundials.c_sundials cimport (N_Vector, sunrealtype, SUNContext, SUNContext_Create,
                                               SUNContext_Free, SUNMatrix, SUNLinearSolver, N_VDestroy,
                                               SUNMatDestroy, SUNLinSolFree)
from scikits.odes.sundials.c_nvector_serial cimport N_VNew_Serial, N_VGetArrayPointer_Serial
from scikits.odes.sundials.c_sunmatrix cimport SUNDenseMatrix, SUNDenseMatrix_Data
from scikits.odes.sundials.c_sundials cimport sunindextype
from scikits.odes.sundials.c_sunlinsol cimport SUNLinSol_Dense
from scikits.odes.sundials.c_cvode cimport (CVodeCreate, CVodeInit, CVodeReInit, CVodeSVtolerances,
                                            CVodeSetUserData, CVodeSetErrHandlerFn, CVodeSetMaxNumSteps,
                                            CVodeSetLinearSolver, CVodeSetJacFn, CVodeSetStopTime,
                                            CVodeSetInitStep, CVodeGetActualInitStep, CVode, CVodeFree,
                                            CV_BDF, CV_NORMAL, CVRhsFn, CVLsJacFn, CVErrHandlerFn,
                                            CVodeGetNumSteps, CVodeGetNumRhsEvals, CVodeGetNumErrTestFails,
                                            CVodeGetNumNonlinSolvConvFails, CVodeGetNumJacEvals)

cnp.import_array()

cdef extern from "small_dense.h":
    # SUNDIALS' dense LU, unrolled for small state counts (see the header)
    SUNLinearSolver SmallDenseLinearSolver(sunindextype n, SUNContext context)
    SUNMatrix SmallDenseMatrix(sunindextype n, SUNContext context)

cdef extern from "small_vector.h":
    # SUNDIALS' serial vector with its per-step operations in one call each (the same doubles; see the header)
    N_Vector SmallSerialVector(sunindextype n, SUNContext context)

ctypedef long long casadi_int
ctypedef int (*casadi_fn)(const double** arg, double** res, casadi_int* iw, double* w, int mem) noexcept nogil

#: What happens at a change of the held input (``Integrator.restart``).  The input jumps at a
#: sample boundary, so the solution has a kink there; the integration always stops exactly at the
#: boundary (``CVodeSetStopTime``).  ``benchmarks/test_bench_simulator.py`` prints steps, evaluations
#: and error of each policy on both rigs.
REINIT = 0            # the default: CVodeReInit at the boundary (order 1, CVODE's initial-step estimate)
REINIT_REUSE_H0 = 1   # CVodeReInit with the previous restart's first step (as CVODES' adjoint checkpoints
                      # do): no estimate (~2 rhs evaluations less a restart), but that step is then the
                      # first estimate's for the whole run, however the motion changes
KEEP_HISTORY = 2      # no restart: the BDF history from before the kink predicts the first step; fewer
                      # steps on paper 1 but 2-5x the position error at the same tolerance (the error
                      # test is fooled by the kink), and more steps on paper 2
POLICIES = {"reinit": REINIT, "reinit-reuse-h0": REINIT_REUSE_H0, "keep-history": KEEP_HISTORY}


cdef struct Kernel:
    casadi_fn fn
    const double* arg[3]    # x, u, p
    double* res[1]
    casadi_int* iw
    double* w


cdef struct Problem:
    Kernel rhs        # f(x, u, p) -> xdot
    Kernel jac        # df/dx (x, u, p), dense column-major n x n
    int n
    double u          # the held input the kernels read
    char message[512]


cdef int _kernel_init(Kernel* k, compiled, double* u, double* p) except -1:
    if compiled.n_arg > 3 or compiled.n_res > 1:
        raise ValueError(f"{compiled.name}: compiled kernels take (x, u, p) and give one output")
    k.fn = <casadi_fn> <size_t> compiled.address
    k.iw = <casadi_int*> malloc(max(compiled.n_iw, 1) * sizeof(casadi_int))
    k.w = <double*> malloc(max(compiled.n_w, 1) * sizeof(double))
    if k.iw == NULL or k.w == NULL:
        raise MemoryError()
    k.arg[0] = NULL
    k.arg[1] = u
    k.arg[2] = p
    k.res[0] = NULL
    return 0


cdef int _rhs(sunrealtype t, N_Vector y, N_Vector ydot, void* data) noexcept:
    cdef Problem* pb = <Problem*> data
    pb.rhs.arg[0] = <double*> N_VGetArrayPointer_Serial(y)   # u and p are fixed pointers
    pb.rhs.res[0] = <double*> N_VGetArrayPointer_Serial(ydot)
    return pb.rhs.fn(pb.rhs.arg, pb.rhs.res, pb.rhs.iw, pb.rhs.w, 0)


cdef int _jac(sunrealtype t, N_Vector y, N_Vector fy, SUNMatrix J, void* data,
              N_Vector tmp1, N_Vector tmp2, N_Vector tmp3) noexcept:
    # SUNDIALS' dense matrix and CasADi's dense output are both column-major: written in place
    cdef Problem* pb = <Problem*> data
    pb.jac.arg[0] = <double*> N_VGetArrayPointer_Serial(y)
    pb.jac.res[0] = <double*> SUNDenseMatrix_Data(J)
    return pb.jac.fn(pb.jac.arg, pb.jac.res, pb.jac.iw, pb.jac.w, 0)


cdef void _error(int code, char* module, char* function, char* msg, void* data) noexcept:
    # keep CVODE's last message for our error text instead of printing it to stderr
    cdef Problem* pb = <Problem*> data
    cdef int i = 0
    while msg[i] != 0 and i < 511:
        pb.message[i] = msg[i]
        i += 1
    pb.message[i] = 0


cdef class Integrator:
    """One CVODE memory on the compiled model: BDF, Newton, dense direct solver, exact Jacobian.

    Parameters
    ----------
    rhs, jac : pneusim.solver.codegen.CompiledFunction
        The model's ``f(x, u, p)`` and ``df/dx(x, u, p)`` (dense), compiled.
    params : ndarray (n_params,)
        The parameter vector, shared: changing it in place changes the model.
    n : int
        Number of states.
    rtol : float
    atol : ndarray (n,)
    max_steps : int
        Internal steps allowed per call of :meth:`advance`.
    linear_algebra : str
        ``"small"`` (default): CVODE's vectors from ``small_vector.h`` and its Newton matrix and linear
        solver from ``small_dense.h``; ``"sundials"``: SUNDIALS' own serial vector, dense matrix and
        dense solver, which compute the same doubles about twice as slowly, kept as the peer the tests
        and the benchmark compare with.
    """
    cdef Problem pb
    cdef SUNContext ctx
    cdef void* mem
    cdef N_Vector y
    cdef N_Vector atol_v
    cdef SUNMatrix A
    cdef SUNLinearSolver LS
    cdef readonly int n
    cdef readonly bint initialized
    cdef public int restart          # one of POLICIES' values
    cdef object keep
    cdef long totals[5]

    def __cinit__(self):
        self.mem = NULL
        self.ctx = NULL
        self.y = NULL
        self.atol_v = NULL
        self.A = NULL
        self.LS = NULL
        self.pb.rhs.iw = NULL
        self.pb.rhs.w = NULL
        self.pb.jac.iw = NULL
        self.pb.jac.w = NULL

    def __init__(self, rhs, jac, double[::1] params, int n, double rtol, double[::1] atol, long max_steps=50000,
                 str linear_algebra="small"):
        cdef int i
        if atol.shape[0] != n:
            raise ValueError(f"{n} absolute tolerances expected, got {atol.shape[0]}")
        self.keep = (rhs, jac, params)   # the kernels call into these libraries and read params in place
        self.n = n
        self.pb.n = n
        self.pb.u = 0.0
        self.pb.message[0] = 0
        _kernel_init(&self.pb.rhs, rhs, &self.pb.u, &params[0])
        _kernel_init(&self.pb.jac, jac, &self.pb.u, &params[0])
        if SUNContext_Create(NULL, &self.ctx) != 0:
            raise MemoryError("SUNContext_Create failed")
        if linear_algebra not in ("small", "sundials"):
            raise ValueError(f"linear_algebra: 'small' or 'sundials', got {linear_algebra!r}")
        small = linear_algebra == "small"
        self.y = SmallSerialVector(n, self.ctx) if small else N_VNew_Serial(n, self.ctx)
        self.atol_v = N_VNew_Serial(n, self.ctx)
        if self.y == NULL or self.atol_v == NULL:
            raise MemoryError()
        for i in range(n):
            N_VGetArrayPointer_Serial(self.y)[i] = 0.0
            N_VGetArrayPointer_Serial(self.atol_v)[i] = atol[i]
        self.mem = CVodeCreate(CV_BDF, self.ctx)
        if self.mem == NULL:
            raise MemoryError("CVodeCreate failed")
        _check(CVodeInit(self.mem, <CVRhsFn> _rhs, 0.0, self.y), "CVodeInit")
        _check(CVodeSVtolerances(self.mem, rtol, self.atol_v), "CVodeSVtolerances")
        _check(CVodeSetUserData(self.mem, &self.pb), "CVodeSetUserData")
        _check(CVodeSetErrHandlerFn(self.mem, <CVErrHandlerFn> _error, &self.pb), "CVodeSetErrHandlerFn")
        _check(CVodeSetMaxNumSteps(self.mem, max_steps), "CVodeSetMaxNumSteps")
        if small:
            self.A = SmallDenseMatrix(n, self.ctx)
            self.LS = SmallDenseLinearSolver(n, self.ctx)
        else:
            # SUNDIALS' own dense matrix and solver: the peer small_dense.h is checked against
            self.A = SUNDenseMatrix(n, n, self.ctx)
            self.LS = SUNLinSol_Dense(self.y, self.A, self.ctx)
        if self.A == NULL or self.LS == NULL:
            raise MemoryError()
        _check(CVodeSetLinearSolver(self.mem, self.LS, self.A), "CVodeSetLinearSolver")
        _check(CVodeSetJacFn(self.mem, <CVLsJacFn> _jac), "CVodeSetJacFn")
        self.restart = REINIT
        self.initialized = False
        for i in range(5):
            self.totals[i] = 0

    def __dealloc__(self):
        if self.mem != NULL:
            CVodeFree(&self.mem)
        if self.LS != NULL:
            SUNLinSolFree(self.LS)
        if self.A != NULL:
            SUNMatDestroy(self.A)
        if self.y != NULL:
            N_VDestroy(self.y)
        if self.atol_v != NULL:
            N_VDestroy(self.atol_v)
        free(self.pb.rhs.iw); free(self.pb.rhs.w); free(self.pb.jac.iw); free(self.pb.jac.w)
        if self.ctx != NULL:
            SUNContext_Free(&self.ctx)

    @property
    def u(self):
        """The input held now."""
        return self.pb.u

    def state(self):
        """A copy of CVODE's current solution vector."""
        if not self.initialized:
            raise RuntimeError("reset the integrator first")
        out = np.empty(self.n)
        memcpy(<double*> cnp.PyArray_DATA(out), N_VGetArrayPointer_Serial(self.y), self.n * sizeof(double))
        return out

    def rhs(self, double[::1] x, double u):
        """``f(x, u, p)`` through the right-hand-side callback CVODE calls (the held input is kept)."""
        cdef double held = self.pb.u
        cdef N_Vector v = N_VNew_Serial(self.n, self.ctx)
        cdef N_Vector out_v = N_VNew_Serial(self.n, self.ctx)
        cdef int flag
        self._check_n(x)
        memcpy(N_VGetArrayPointer_Serial(v), &x[0], self.n * sizeof(double))
        self.pb.u = u
        flag = _rhs(0.0, v, out_v, &self.pb)
        self.pb.u = held
        out = np.empty(self.n)
        memcpy(<double*> cnp.PyArray_DATA(out), N_VGetArrayPointer_Serial(out_v), self.n * sizeof(double))
        N_VDestroy(v)
        N_VDestroy(out_v)
        return out if flag == 0 else None

    def jacobian(self, double[::1] x, double u):
        """``df/dx`` (n, n) through the Jacobian callback CVODE calls, on its dense matrix type."""
        cdef double held = self.pb.u
        cdef SUNMatrix J = SUNDenseMatrix(self.n, self.n, self.ctx)
        cdef N_Vector v = N_VNew_Serial(self.n, self.ctx)
        cdef int flag
        self._check_n(x)
        memcpy(N_VGetArrayPointer_Serial(v), &x[0], self.n * sizeof(double))
        self.pb.u = u
        flag = _jac(0.0, v, v, J, &self.pb, v, v, v)
        self.pb.u = held
        out = np.empty((self.n, self.n), order="F")
        memcpy(<double*> cnp.PyArray_DATA(out), SUNDenseMatrix_Data(J), self.n * self.n * sizeof(double))
        SUNMatDestroy(J)
        N_VDestroy(v)
        return np.ascontiguousarray(out) if flag == 0 else None

    cdef int _check_n(self, double[::1] x) except -1:
        if x.shape[0] != self.n:
            raise ValueError(f"{self.n} states expected, got {x.shape[0]}")
        return 0

    def reset(self, double t0, double[::1] x0, double u):
        """Start again at ``(t0, x0)`` with input ``u``; the counters start from zero."""
        cdef int i
        self._check_n(x0)
        self.pb.u = u
        memcpy(N_VGetArrayPointer_Serial(self.y), &x0[0], self.n * sizeof(double))
        _check(CVodeSetInitStep(self.mem, 0.0), "CVodeSetInitStep")   # CVODE estimates the first step
        _check(CVodeReInit(self.mem, t0, self.y), "CVodeReInit")
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
        cdef sunrealtype h = 0.0
        if u != self.pb.u:
            self.pb.u = u
            if self.restart != KEEP_HISTORY:
                # restart the BDF history at the kink; CVodeReInit keeps the initial step set last
                if self.restart == REINIT_REUSE_H0:
                    CVodeGetActualInitStep(self.mem, &h)   # the previous restart's first step
                    CVodeSetInitStep(self.mem, h)
                self._bank()
                flag = CVodeReInit(self.mem, t_now, self.y)
                if flag < 0:
                    return flag
        # the input is held up to t_stop and may change there: never step past it
        flag = CVodeSetStopTime(self.mem, t_stop)
        if flag < 0:
            return flag
        return CVode(self.mem, t_stop, self.y, t_reached, CV_NORMAL)

    def advance(self, double t_now, double t_stop, double u):
        """Integrate from ``t_now`` (the time of the state) to ``t_stop`` with ``u`` held.

        Returns ``(flag, t_reached, message)``; :meth:`state` gives the state.
        """
        cdef sunrealtype t_reached = t_now
        cdef int flag
        if not self.initialized:
            raise RuntimeError("reset the integrator first")
        self.pb.message[0] = 0
        flag = self._advance(t_now, t_stop, u, &t_reached)
        return flag, t_reached, self.message(flag)

    cdef str message(self, int flag):
        return self.pb.message.decode("utf-8", "replace") if flag < 0 and self.pb.message[0] != 0 else ""

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


cdef int _check(int flag, str where) except -1:
    if flag < 0:
        raise RuntimeError(f"{where} failed with flag {flag}")
    return 0


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
        self.integ.pb.message[0] = 0
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
        return flag, t_reached, self.integ.message(flag)
