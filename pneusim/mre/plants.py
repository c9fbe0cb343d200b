"""Plants of the mixed-reality environment besides the simulator, and the ``--plant`` text.

* ``sim``: :class:`pneusim.plant.SimulatedPlant` (paced by the loop's clock in real-time mode);
* ``replay:FILE``: :class:`ReplayPlant`, a recording played back (**open loop**);
* ``udp:HOST:PORT``: :class:`pneusim.mre.udp.UdpPlant`, a rig server in another process;
* ``nidaqmx``: :class:`pneusim.mre.daq.DaqPlant`, a real rig through an NI card.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import PneusimError
from ..plant import Measurement

__all__ = ["ReplayPlant", "PlantChoice", "parse_plant", "PLANT_KINDS"]

PLANT_KINDS = ("sim", "replay:FILE", "udp:HOST:PORT", "nidaqmx")


@dataclass(frozen=True)
class PlantChoice:
    """A parsed ``--plant`` value: ``kind`` in sim/replay/udp/nidaqmx and its argument."""

    kind: str
    path: str = ""
    host: str = ""
    port: int = 0

    @property
    def text(self) -> str:
        return {"sim": "sim", "nidaqmx": "nidaqmx", "replay": f"replay:{self.path}",
                "udp": f"udp:{self.host}:{self.port}"}[self.kind]


def parse_plant(text: str, where: str = "--plant") -> PlantChoice:
    """``sim``, ``replay:FILE``, ``udp:HOST:PORT`` or ``nidaqmx``; anything else is refused in one line."""
    text = str(text).strip()
    if text in ("sim", "nidaqmx"):
        return PlantChoice(text)
    if text.startswith("replay:") and len(text) > len("replay:"):
        return PlantChoice("replay", path=text[len("replay:"):])
    if text.startswith("udp:"):
        host, _, port = text[4:].rpartition(":")
        if host and port.isdigit() and 0 < int(port) < 65536:
            return PlantChoice("udp", host=host, port=int(port))
        raise PneusimError(f"{where} {text!r}: expected udp:HOST:PORT with a port in 1..65535, "
                           "e.g. udp:127.0.0.1:5555")
    raise PneusimError(f"{where} {text!r}: expected one of {', '.join(PLANT_KINDS)}")


class ReplayPlant:
    """A recording played back sample by sample: **open loop**.

    ``measure`` returns the recorded position (and pressures) of the current
    sample whatever the loop commands; ``step`` logs the loop's command
    (:attr:`commands_V`) and moves to the next sample.  The controller and the
    identifiers therefore run on real data in real time, but their commands do
    not act on what is measured: the loop is open, and the identifiers see the
    loop's commands beside measurements that were produced by the recording's own
    commands.  Use it to rehearse the timing and the software chain, not to judge
    a controller.

    Parameters
    ----------
    recording : Recording
    start_index : int
        Recorded sample returned by the first ``measure`` (the warm-up consumes samples from here).
    """

    open_loop = True

    def __init__(self, recording, start_index: int = 0):
        self.recording = recording
        self.sample_time_s = recording.sample_time_s
        self._start = int(start_index)
        self._i = self._start
        self.commands_V: list[float] = []
        n = recording.n_samples
        self._pa = recording.pressure_a_Pa if recording.pressure_a_Pa is not None else np.full(n, np.nan)
        self._pb = recording.pressure_b_Pa if recording.pressure_b_Pa is not None else np.full(n, np.nan)

    @property
    def remaining(self) -> int:
        return self.recording.n_samples - self._i

    def reset(self, position_m: float = 0.0, command_V: float = 0.0, t0_s: float = 0.0) -> None:
        self._i = self._start
        self._t0 = float(t0_s)
        self.commands_V = []

    def measure(self) -> Measurement:
        i = self._i
        if i >= self.recording.n_samples:
            raise PneusimError(f"replay: the recording {self.recording.source or ''} ends after "
                               f"{self.recording.n_samples} samples; shorten --duration")
        return Measurement(self._t0 + (i - self._start) * self.sample_time_s, float(self.recording.position_m[i]),
                           float(self._pa[i]), float(self._pb[i]))

    def step(self, command_V: float) -> None:
        self.commands_V.append(float(command_V))
        self._i += 1

    def safe_stop(self, null_V: float | None = None) -> None:
        """Log the valve-to-null command that ends the run (nothing acts on it: open loop)."""
        self.null_V_sent = null_V
