"""Sensors: what the data acquisition adds to the true signals (noise, converter steps).

Position: Gaussian noise, then an ``n``-bit converter over ``0 .. stroke`` whose
codes saturate at the ends.  Pressures: Gaussian noise, then rounding to the
converter's step.  All draws come from one seeded generator, so a run is
reproducible from its seed.
"""

from __future__ import annotations

import numpy as np

from .rig import Rig

__all__ = ["Sensors"]


class Sensors:
    """Noise and quantisation of a rig's sensors.

    Parameters
    ----------
    rig : Rig
        Supplies ``position_noise_std_m``, ``position_adc_bits``, ``pressure_noise_std_Pa``,
        ``pressure_quantum_Pa`` and ``stroke_m``.
    seed : int
        Seed of the noise generator.
    noise_scale : float
        Multiplies both noise levels (0 gives ideal sensors, still quantised).
    """

    def __init__(self, rig: Rig, seed: int = 0, noise_scale: float = 1.0):
        self.stroke_m = rig.stroke_m
        self.position_std_m = rig.params["position_noise_std_m"] * noise_scale
        bits = int(rig.params["position_adc_bits"])
        self.position_quantum_m = self.stroke_m / (2**bits - 1) if bits > 0 else 0.0
        self.pressure_std_Pa = rig.params["pressure_noise_std_Pa"] * noise_scale
        self.pressure_quantum_Pa = rig.params["pressure_quantum_Pa"]
        self.rng = np.random.default_rng(seed)
        self._block: list[float] = []

    def _normal(self) -> float:
        # standard normals drawn in blocks: the same stream as one draw per call, without the
        # per-call cost inside a 1 kHz loop
        if not self._block:
            self._refill()
        return self._block.pop()

    def _refill(self) -> None:
        # stored reversed, so that pop() hands the draws out in the generator's order
        self._block = self.rng.standard_normal(4096).tolist()[::-1]

    def take_normals(self, count: int) -> np.ndarray:
        """The next ``count`` draws of :meth:`_normal`'s stream, as an array (for the compiled loop)."""
        out = np.empty(count)
        i = 0
        while i < count:
            if not self._block:
                self._refill()
            m = min(len(self._block), count - i)
            out[i:i + m] = self._block[:-m - 1:-1]  # the block is stored reversed; pop() takes from its end
            del self._block[-m:]
            i += m
        return out

    def position(self, true_m: float) -> float:
        y = true_m + (self.position_std_m * self._normal() if self.position_std_m > 0 else 0.0)
        if self.position_quantum_m > 0:
            y = min(max(y, 0.0), self.stroke_m)
            y = round(y / self.position_quantum_m) * self.position_quantum_m
        return y

    def pressure(self, true_Pa: float) -> float:
        y = true_Pa + (self.pressure_std_Pa * self._normal() if self.pressure_std_Pa > 0 else 0.0)
        if self.pressure_quantum_Pa > 0:
            y = round(y / self.pressure_quantum_Pa) * self.pressure_quantum_Pa
        return y
