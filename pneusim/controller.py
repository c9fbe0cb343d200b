"""Controllers: anything that turns (time, reference, measured position) into a valve command.

A controller is stepped once per sample, on the measured (noisy, quantised)
position, and its command is held until the next sample (zero-order hold).
Plug in your own by implementing :class:`Controller`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from .errors import PneusimError

__all__ = ["Controller", "ProportionalController", "controller_from_metadata"]


@runtime_checkable
class Controller(Protocol):
    def reset(self) -> None:
        """Forget any internal state before a run."""

    def command(self, t_s: float, reference_m: float, measured_m: float) -> float:
        """Valve command in V for this sample."""

    def metadata(self) -> dict[str, str]:
        """Recording metadata describing this controller (``controller`` and its constants)."""


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
        if not self.u_min_V < self.u_max_V:
            raise PneusimError(f"controller: u_min_V ({self.u_min_V}) must be below u_max_V ({self.u_max_V})")

    def reset(self) -> None:
        pass

    def command(self, t_s: float, reference_m: float, measured_m: float) -> float:
        u = self.u0_V + self.kp_V_per_m * (reference_m - measured_m)
        return min(max(u, self.u_min_V), self.u_max_V)

    def metadata(self) -> dict[str, str]:
        return {"controller": "proportional", "kp_V_per_m": repr(self.kp_V_per_m), "u0_V": repr(self.u0_V),
                "u_min_V": repr(self.u_min_V), "u_max_V": repr(self.u_max_V)}


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
