"""ODE backends that integrate the model between sample instants with the input held.

* :class:`CvodeBackend` — SUNDIALS CVODE (BDF, Newton, dense direct solver with
  the exact CasADi Jacobian), the SUNDIALS library ``scikits.odes`` is built on,
  created and driven from C through ``scikits.odes``' Cython declarations
  (:mod:`pneusim.solver._cvode_compiled`); right-hand side and Jacobian are the
  CasADi-generated C called by CVODE directly, and the integration to each sample
  (or a whole sample loop) runs without Python in between.
* :class:`ScipyBackend` — SciPy's ``solve_ivp`` (Radau, BDF or LSODA) with the
  same CasADi functions, restarted at every input change: the reference for
  cross-checks and the peer in benchmarks.

Both have the same small interface: ``reset(t0, x0)``, ``advance(t_stop, u)``
returning the state at ``t_stop``, and ``stats``.
"""

from __future__ import annotations

import weakref

import numpy as np

from ..errors import SolverError
from ..model import ActuatorModel

__all__ = ["CvodeBackend", "ScipyBackend", "make_backend", "BACKENDS", "state_scales"]


def state_scales(model: ActuatorModel, stroke_m: float) -> np.ndarray:
    """Typical magnitude of each state, for absolute tolerances."""
    scale = {"position_m": stroke_m, "velocity_m_per_s": 1.0, "pressure_a_Pa": 1e5, "pressure_b_Pa": 1e5,
             "spool_opening": 1.0, "spool_rate_per_s": 100.0, "temperature_a_K": 300.0,
             "temperature_b_K": 300.0, "supply_pressure_Pa": 1e5}
    return np.array([scale.get(s, 1.0) for s in model.state_names])


#: compiled rhs and Jacobian of each model object, for as long as the model lives
_COMPILED: "weakref.WeakKeyDictionary[ActuatorModel, dict]" = weakref.WeakKeyDictionary()


class _Backend:
    name = ""

    def __init__(self, model: ActuatorModel, params: np.ndarray, *, rtol: float = 1e-6,
                 atol: np.ndarray | None = None, stroke_m: float = 0.3):
        self.model = model
        self.params = np.ascontiguousarray(params, dtype=float)
        self.rtol = float(rtol)
        self.atol = rtol * state_scales(model, stroke_m) if atol is None else np.asarray(atol, float)
        self.t = 0.0
        self.x = None

    def _fail(self, message: str, t: float, x: np.ndarray):
        state = ", ".join(f"{n}={v:.6g}" for n, v in zip(self.model.state_names, x))
        raise SolverError(f"{self.name} failed at t = {t:.6f} s ({message}); state: {state}")


class CvodeBackend(_Backend):
    """SUNDIALS CVODE (from the library scikits.odes is built on) driven from C on the compiled model."""

    name = "cvode"

    def __init__(self, model, params, *, rtol=1e-6, atol=None, stroke_m=0.3, max_steps=50000,
                 linear_algebra="small"):
        super().__init__(model, params, rtol=rtol, atol=atol, stroke_m=stroke_m)
        if linear_algebra != "small":
            self.name = f"cvode-{linear_algebra}"
        from . import _cvode_compiled as fast
        from .codegen import compile_functions

        compiled = _COMPILED.get(model)
        if compiled is None:  # generating the C source to look up the library takes ~10 ms: once per model
            compiled = _COMPILED[model] = compile_functions([model.rhs, model.jac], prefix=_prefix(model))
        n = len(model.state_names)
        # CVODE memory, vectors, dense matrix and solver, with the CasADi kernels as C callbacks
        self._integrator = fast.Integrator(compiled[model.rhs.name()], compiled[model.jac.name()], self.params,
                                           n, self.rtol, np.ascontiguousarray(self.atol, dtype=float), max_steps,
                                           linear_algebra)

    def set_params(self, params: np.ndarray):
        self.params[:] = params

    def reset(self, t0: float, x0: np.ndarray):
        self.t = float(t0)
        self.x = np.array(x0, dtype=float)
        # the input is unknown until the first advance: NaN equals no input, so the first advance restarts
        self._integrator.reset(self.t, np.ascontiguousarray(self.x), float("nan"))

    def advance(self, t_stop: float, u: float) -> np.ndarray:
        # stops exactly at t_stop; a changed input goes on from there with the BDF history kept
        flag, t_reached, message = self._integrator.advance(self.t, t_stop, u)
        if flag < 0:
            self.failed(flag, t_reached, message)
        self.t = t_stop
        self.x = self._integrator.state()
        return self.x

    def failed(self, flag: int, t_reached: float, message: str):
        """Raise :class:`SolverError` for a CVODE failure (flag < 0) at ``t_reached``."""
        self._fail(f"CVODE flag {flag}: {message}" if message else f"CVODE flag {flag}", t_reached,
                   self._integrator.state())

    def sync(self, t: float):
        """Take over time and state after the integrator was advanced from C (a compiled loop)."""
        self.t = float(t)
        self.x = self._integrator.state()

    @property
    def stats(self) -> dict:
        if not self._integrator.initialized:
            return {}
        return self._integrator.statistics()


class ScipyBackend(_Backend):
    """SciPy ``solve_ivp`` on the same CasADi functions (evaluated from Python)."""

    def __init__(self, model, params, *, method="Radau", rtol=1e-6, atol=None, stroke_m=0.3):
        super().__init__(model, params, rtol=rtol, atol=atol, stroke_m=stroke_m)
        self.method = method
        self.name = f"scipy-{method}"
        self.n_rhs = 0

    def set_params(self, params):
        self.params[:] = params

    def reset(self, t0, x0):
        self.t = float(t0)
        self.x = np.array(x0, dtype=float)

    def advance(self, t_stop, u):
        from scipy.integrate import solve_ivp

        rhs, jac, p = self.model.rhs, self.model.jac, self.params

        def f(t, x):
            self.n_rhs += 1
            return np.asarray(rhs(x, u, p)).ravel()

        def j(t, x):
            return np.asarray(jac(x, u, p))

        kwargs = {"jac": j} if self.method in ("Radau", "BDF", "LSODA") else {}
        sol = solve_ivp(f, (self.t, t_stop), self.x, method=self.method, rtol=self.rtol, atol=self.atol, **kwargs)
        if not sol.success:
            self._fail(sol.message, float(sol.t[-1]), sol.y[:, -1])
        self.t = t_stop
        self.x = sol.y[:, -1].copy()
        return self.x

    @property
    def stats(self):
        return {"rhs_evaluations": self.n_rhs}


BACKENDS = ("cvode", "cvode-sundials", "scipy-radau", "scipy-bdf", "scipy-lsoda")


def make_backend(name: str, model: ActuatorModel, params: np.ndarray, **options):
    """Backend by name: ``cvode`` (default), ``cvode-sundials`` (CVODE with SUNDIALS' own serial vector,
    dense matrix and dense solver instead of ``small_vector.h``'s and ``small_dense.h``'s: the same
    results to the last bit, about half the speed), ``scipy-radau``, ``scipy-bdf``, ``scipy-lsoda``."""
    if name == "cvode":
        return CvodeBackend(model, params, **options)
    if name == "cvode-sundials":
        return CvodeBackend(model, params, linear_algebra="sundials", **options)
    if name.startswith("scipy-"):
        method = {"radau": "Radau", "bdf": "BDF", "lsoda": "LSODA"}.get(name[6:])
        if method:
            return ScipyBackend(model, params, method=method, **options)
    raise ValueError(f"unknown solver backend {name!r}; expected one of {', '.join(BACKENDS)}")


def _prefix(model: ActuatorModel) -> str:
    return "pneusim_" + "_".join(e.name for e in model.effects) if model.effects else "pneusim_nominal"
