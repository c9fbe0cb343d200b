"""Plants stepped sample by sample: the simulator now, replayed or real rigs later.

A plant has one small interface (:class:`Plant`): ``reset`` to a resting
state, ``measure`` what the sensors read now, and ``step`` with the valve
command held for one sample.  The simulator, a controller and an online
identifier can therefore run in one loop, sample by sample, which is what the
mixed-reality environment of the first paper does.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Mapping, Protocol, Sequence

import numpy as np

from .controller import ProportionalController
from .errors import PneusimError
from .model import ActuatorModel, Effect
from .rig import Rig
from .sensors import Sensors
from .solver.backends import CvodeBackend, make_backend

__all__ = ["Plant", "Measurement", "SimulatedPlant"]

_MODELS: dict[tuple, ActuatorModel] = {}


def _model_for(effects: Sequence[Effect] = ()) -> ActuatorModel:
    """The :class:`ActuatorModel` with ``effects``, built once per process for each set of effects.

    Building the symbolic model takes ~20 ms, a good part of a short simulation; the
    model is immutable, so plants with the same effects share it.
    """
    key = tuple((type(e), e.to_text()) for e in effects)
    model = _MODELS.get(key)
    if model is None:
        if len(_MODELS) >= 64:
            _MODELS.pop(next(iter(_MODELS)))
        model = _MODELS[key] = ActuatorModel(effects)
    return model


@dataclass(frozen=True)
class Measurement:
    """What the data acquisition reads at one sample instant (SI units, absolute pressures)."""

    t_s: float
    position_m: float
    pressure_a_Pa: float = float("nan")
    pressure_b_Pa: float = float("nan")


class Plant(Protocol):
    sample_time_s: float

    def reset(self, position_m: float, command_V: float, t0_s: float = 0.0) -> None: ...

    def measure(self) -> Measurement: ...

    def step(self, command_V: float) -> None: ...


class SimulatedPlant:
    """The physical model as a plant: CVODE between samples, sensors at the samples.

    Parameters
    ----------
    rig : Rig
    effects : sequence of Effect
        Optional effects switched on.
    backend : str
        ``cvode`` (default) or a SciPy reference backend (``scipy-radau`` ...).
    rtol : float
        Relative tolerance of the ODE solver.
    seed : int
        Seed of the sensor noise.
    noise_scale : float
        Multiplies the rig's sensor noise levels (0 for ideal sensors).
    model : ActuatorModel or None
        The model to integrate (default: the model of ``effects``, built once per process).
    solver_options : mapping or None
        Further options of the ODE backend (e.g. ``max_steps`` between two samples).
    """

    def __init__(self, rig: Rig, effects: Sequence[Effect] = (), *, backend: str = "cvode", rtol: float = 1e-6,
                 seed: int = 0, noise_scale: float = 1.0, model: ActuatorModel | None = None,
                 solver_options: Mapping | None = None):
        self.rig = rig
        self.model = model if model is not None else _model_for(effects)
        self.params = self.model.param_vector(rig)
        self.sample_time_s = rig.sample_time_s
        self.solver = make_backend(backend, self.model, self.params, rtol=rtol, stroke_m=rig.stroke_m,
                                   **dict(solver_options or {}))
        self.sensors = Sensors(rig, seed=seed, noise_scale=noise_scale)
        self.delay_s = self.model.command_delay_s()
        self._k = 0
        self._t0 = 0.0

    @property
    def t_s(self) -> float:
        return self._t0 + self._k * self.sample_time_s

    @property
    def state(self) -> np.ndarray:
        """True (noise-free) state at the current sample, in ``model.state_names`` order."""
        return self.solver.x

    def reset(self, position_m: float, command_V: float, t0_s: float = 0.0,
              pressures_Pa: tuple[float, float] | None = None) -> None:
        """Rest at ``position_m`` with ``command_V`` applied (and already seen by a delayed valve)."""
        self._t0, self._k = float(t0_s), 0
        x0 = self.model.initial_state(self.rig, position_m, command_V, pressures_Pa=pressures_Pa)
        self.solver.reset(self._t0, x0)
        self._seen_V = float(command_V)
        self._pending: deque[tuple[float, float]] = deque()

    def measure(self) -> Measurement:
        x = self.solver.x
        return Measurement(self.t_s, self.sensors.position(x[0]), self.sensors.pressure(x[2]),
                           self.sensors.pressure(x[3]))

    def compiled_loop(self, controller=None):
        """The sample loop in C for this plant with the built-in parts, or ``None``.

        Available when the plant integrates with CVODE, reads through the built-in
        :class:`Sensors` and ``controller`` is ``None`` (open loop) or exactly a
        :class:`~pneusim.controller.ProportionalController`; :func:`pneusim.simulate.simulate`
        then runs the loop without Python per sample, with the same results as
        :meth:`measure` / :meth:`step`.  Call :meth:`sync_from` afterwards to bring this plant
        up to where the loop stopped.
        """
        if type(self.solver) is not CvodeBackend or type(self.sensors) is not Sensors:
            return None
        if controller is not None and type(controller) is not ProportionalController:
            return None
        # the compiled extension, as the CVODE backend imports it: the SciPy backends run without a build
        from .solver._cvode_compiled import SampleLoop

        if not hasattr(self, "_pending"):
            raise PneusimError("reset the plant before running its loop")
        s = self.sensors
        return SampleLoop(self.solver._integrator, self._t0, self._k, self.solver.t, self.sample_time_s,
                          self.delay_s, self._seen_V, list(self._pending), controller, s.position_std_m,
                          s.position_quantum_m, s.stroke_m, s.pressure_std_Pa, s.pressure_quantum_Pa)

    def sync_from(self, loop) -> None:
        """Take over the state a :meth:`compiled_loop` reached."""
        self._k = loop.k
        self._seen_V = loop.seen_V
        self._pending = deque(loop.pending)
        self.solver.sync(loop.t)

    def step(self, command_V: float) -> None:
        """Hold ``command_V`` for one sample; a transport delay makes the valve see it later."""
        t_now = self.t_s
        t_end = self._t0 + (self._k + 1) * self.sample_time_s
        if self.delay_s <= 0.0:
            self.solver.advance(t_end, command_V)
        else:
            self._pending.append((t_now + self.delay_s, float(command_V)))
            t = t_now
            eps = 1e-9 * self.sample_time_s
            while self._pending and self._pending[0][0] < t_end - eps:
                t_switch, value = self._pending.popleft()
                if t_switch > t + eps:
                    self.solver.advance(t_switch, self._seen_V)
                    t = t_switch
                self._seen_V = value
            self.solver.advance(t_end, self._seen_V)
        self._k += 1
