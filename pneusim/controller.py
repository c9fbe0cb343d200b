"""Controllers: anything that turns (time, reference, measured position) into a valve command.

A controller is stepped once per sample, on the measured (noisy, quantised)
position, and its command is held until the next sample (zero-order hold).
Plug in your own by implementing :class:`Controller`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from .errors import PneusimError

__all__ = ["Controller", "ProportionalController", "PIDController", "controller_from_metadata"]


@runtime_checkable
class Controller(Protocol):
    def reset(self) -> None:
        """Forget any internal state before a run."""

    def command(self, t_s: float, reference_m: float, measured_m: float) -> float:
        """Valve command in V for this sample."""

    def metadata(self) -> dict[str, str]:
        """Recording metadata describing this controller (``controller`` and its constants)."""


def _check_output_limits(u_min_V: float, u_max_V: float) -> None:
    """The valve command's limits of a controller, V: the lower one below the upper one."""
    if not u_min_V < u_max_V:
        raise PneusimError(f"controller: u_min_V ({u_min_V}) must be below u_max_V ({u_max_V})")


@dataclass
class ProportionalController:
    """``u = clip(u0_V + kp_V_per_m * (reference_m - position_m), u_min_V, u_max_V)``.

    The controller of ``shared/spec/recording-format.md``.
    """

    kp_V_per_m: float
    u0_V: float = 5.0
    u_min_V: float = 0.0
    u_max_V: float = 10.0

    def __post_init__(self):
        _check_output_limits(self.u_min_V, self.u_max_V)

    def reset(self) -> None:
        pass

    def command(self, t_s: float, reference_m: float, measured_m: float) -> float:
        u = self.u0_V + self.kp_V_per_m * (reference_m - measured_m)
        return min(max(u, self.u_min_V), self.u_max_V)

    def metadata(self) -> dict[str, str]:
        return {"controller": "proportional", "kp_V_per_m": repr(self.kp_V_per_m), "u0_V": repr(self.u0_V),
                "u_min_V": repr(self.u_min_V), "u_max_V": repr(self.u_max_V)}


@dataclass
class PIDController:
    """Discrete PID position controller with anti-windup, for rigs that need integral action.

    At each sample (sample time ``Ts``), with ``e = reference_m - measured_m``::

        d(k) = filtered derivative of -measured_m (first-order filter, time constant derivative_filter_s)
        v    = u0_V + kp_V_per_m e + i(k) + kd_V_s_per_m d(k)
        u    = clip(v, u_min_V, u_max_V)
        i(k+1) = i(k) + ki_V_per_m_s Ts e      unless u is saturated and e pushes further into saturation

    The derivative acts on the measurement (no kick on reference steps); the
    integrator is frozen while the output is clipped in the direction the error
    drives it (conditional integration), so it does not wind up against the
    valve's limits.  With ``ki = kd = 0`` it is exactly :class:`ProportionalController`.

    Parameters
    ----------
    kp_V_per_m, ki_V_per_m_s, kd_V_s_per_m : float
        Proportional [V/m], integral [V/(m s)] and derivative [V s/m] gains.
    sample_time_s : float
        Sample time the controller is stepped at, s.
    u0_V, u_min_V, u_max_V : float
        Offset (valve null) and output limits, V.
    derivative_filter_s : float
        Time constant of the derivative's first-order filter, s (0: unfiltered difference).
    """

    kp_V_per_m: float
    ki_V_per_m_s: float = 0.0
    kd_V_s_per_m: float = 0.0
    sample_time_s: float = 0.001
    u0_V: float = 5.0
    u_min_V: float = 0.0
    u_max_V: float = 10.0
    derivative_filter_s: float = 0.0

    def __post_init__(self):
        _check_output_limits(self.u_min_V, self.u_max_V)
        if not self.sample_time_s > 0:
            raise PneusimError(f"controller: sample_time_s must be positive, got {self.sample_time_s}")
        if self.derivative_filter_s < 0:
            raise PneusimError(f"controller: derivative_filter_s must be >= 0, got {self.derivative_filter_s}")
        self.reset()

    def reset(self) -> None:
        self.integral_V = 0.0
        self.derivative_m_per_s = 0.0
        self._last_m: float | None = None

    def command(self, t_s: float, reference_m: float, measured_m: float) -> float:
        ts = self.sample_time_s
        e = reference_m - measured_m
        if self._last_m is not None:
            raw = -(measured_m - self._last_m) / ts
            alpha = ts / (self.derivative_filter_s + ts)
            self.derivative_m_per_s += alpha * (raw - self.derivative_m_per_s)
        self._last_m = measured_m
        v = self.u0_V + self.kp_V_per_m * e + self.integral_V + self.kd_V_s_per_m * self.derivative_m_per_s
        u = min(max(v, self.u_min_V), self.u_max_V)
        step = self.ki_V_per_m_s * ts * e
        if not ((v > self.u_max_V and step > 0) or (v < self.u_min_V and step < 0)):
            self.integral_V += step
        return u

    def metadata(self) -> dict[str, str]:
        # 'controller' is reserved by the recording format for the proportional law; a PID is described
        # under its own keys so that its recordings stay valid pneusim-recording/1 files
        return {"controller_kind": "pid", "pid_kp_V_per_m": repr(self.kp_V_per_m),
                "pid_ki_V_per_m_s": repr(self.ki_V_per_m_s), "pid_kd_V_s_per_m": repr(self.kd_V_s_per_m),
                "pid_u0_V": repr(self.u0_V), "pid_u_min_V": repr(self.u_min_V), "pid_u_max_V": repr(self.u_max_V),
                "pid_derivative_filter_s": repr(self.derivative_filter_s)}


def controller_from_metadata(meta: dict[str, str], where: str = "recording") -> ProportionalController:
    """The controller a closed-loop recording names in its metadata."""
    kind = meta.get("controller")
    if kind != "proportional":
        raise PneusimError(f"{where}: closed-loop re-run needs 'controller: proportional' in the metadata, "
                           f"got {kind!r}")
    try:
        return ProportionalController(*(float(meta[k]) for k in ("kp_V_per_m", "u0_V", "u_min_V", "u_max_V")))
    except KeyError as exc:
        raise PneusimError(f"{where}: metadata key {exc.args[0]!r} is missing for the proportional controller") from None
