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
from typing import Protocol, Sequence

import numpy as np

from .model import ActuatorModel, Effect
from .rig import Rig
from .sensors import Sensors
from .solver.backends import make_backend

__all__ = ["Plant", "Measurement", "SimulatedPlant"]


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
    """

    def __init__(self, rig: Rig, effects: Sequence[Effect] = (), *, backend: str = "cvode", rtol: float = 1e-6,
                 seed: int = 0, noise_scale: float = 1.0, model: ActuatorModel | None = None):
        self.rig = rig
        self.model = model if model is not None else ActuatorModel(effects)
        self.params = self.model.param_vector(rig)
        self.sample_time_s = rig.sample_time_s
        self.solver = make_backend(backend, self.model, self.params, rtol=rtol, stroke_m=rig.stroke_m)
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
