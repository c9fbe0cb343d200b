"""Experiments: what is done to the rig, separate from the rig and the model.

An :class:`Experiment` is a sampled signal (the valve command for ``open``
loop, the position reference for ``closed`` loop), a controller for closed
loop, and a warm-up during which the first sample is held so that a recording
does not start from an artificial rest state.  The signal generators below are
seeded and return arrays at the sample instants.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .controller import Controller, ProportionalController
from .errors import PneusimError
from .rig import Rig

__all__ = ["Experiment", "multisine", "random_steps", "pulse_train", "command_doublets", "Recentering",
           "recentering_doublets",
           "standard_experiment", "INPUT_KINDS", "default_controller"]

INPUT_KINDS = ("multisine", "steps", "pulses")

#: proportional gains whose 10 %-of-stroke step overshoots by < 5 % at the rigs' typical values
DEFAULT_KP_V_PER_M = {"paper1-mre": 40.0, "paper2-enfield": 60.0}


@dataclass
class Experiment:
    """A description of one run on a rig.

    Attributes
    ----------
    loop : {'open', 'closed'}
    sample_time_s : float
    signal : ndarray, shape (N,)
        Valve command in V (open loop) or position reference in m (closed loop).
    controller : Controller or None
        Required for closed loop.
    warmup_s : float
        Time before ``t = 0`` during which the first sample is held.
    initial_position_m : float or None
        Where the piston rests before the warm-up; default: the first
        reference (closed loop) or mid-stroke (open loop).
    """

    loop: str
    sample_time_s: float
    signal: np.ndarray
    controller: Controller | None = None
    warmup_s: float = 1.0
    initial_position_m: float | None = None
    initial_pressures_Pa: tuple[float, float] | None = None
    description: str = ""
    metadata: dict = field(default_factory=dict)
    #: open loop only: ``supervisor(k, measured_position_m) -> command_V or None`` may replace the planned
    #: command of sample ``k`` (an operator bringing a drifting piston back); None keeps the plan
    supervisor: object = None

    def __post_init__(self):
        self.signal = np.asarray(self.signal, dtype=float).ravel()
        if self.loop not in ("open", "closed"):
            raise PneusimError(f"experiment loop must be 'open' or 'closed', got {self.loop!r}")
        if self.loop == "closed" and self.controller is None:
            raise PneusimError("a closed-loop experiment needs a controller")
        if not self.sample_time_s > 0:
            raise PneusimError(f"sample_time_s must be positive, got {self.sample_time_s}")
        if self.signal.size < 2 or not np.all(np.isfinite(self.signal)):
            raise PneusimError("the experiment signal must hold at least 2 finite samples")
        if self.warmup_s < 0:
            raise PneusimError(f"warmup_s must not be negative, got {self.warmup_s}")
        if self.supervisor is not None and self.loop != "open":
            raise PneusimError("a supervisor replaces planned open-loop commands; a closed loop has its controller")

    @property
    def n_samples(self) -> int:
        return int(self.signal.size)

    @property
    def time_s(self) -> np.ndarray:
        return np.arange(self.n_samples) * self.sample_time_s


def multisine(time_s, components, offset=0.0):
    """``offset + sum(a * cos(2 pi f t + phase))`` for ``components = [(a, f_Hz[, phase_rad]), ...]``."""
    t = np.asarray(time_s, dtype=float)
    y = np.full_like(t, float(offset))
    for comp in components:
        a, f = comp[0], comp[1]
        phase = comp[2] if len(comp) > 2 else 0.0
        y += a * np.cos(2 * np.pi * f * t + phase)
    return y


def random_steps(n, sample_time_s, low, high, hold_s=(1.0, 4.0), rng=None):
    """Piecewise-constant levels uniform in ``[low, high]``, each held a uniform time in ``hold_s``."""
    rng = np.random.default_rng(rng)
    y = np.empty(n)
    k = 0
    while k < n:
        length = max(1, int(round(rng.uniform(*hold_s) / sample_time_s)))
        y[k:k + length] = rng.uniform(low, high)
        k += length
    return y


def pulse_train(n, sample_time_s, base, amplitude=(0.1, 0.3), width_s=(0.02, 0.12), rest_s=(0.2, 0.8),
                rng=None):
    """Impulse-type excitation: short pulses of random sign and height about ``base``."""
    rng = np.random.default_rng(rng)
    y = np.full(n, float(base))
    k = int(round(rng.uniform(*rest_s) / sample_time_s))
    while k < n:
        width = max(1, int(round(rng.uniform(*width_s) / sample_time_s)))
        y[k:k + width] = base + rng.choice((-1.0, 1.0)) * rng.uniform(*amplitude)
        k += width + max(1, int(round(rng.uniform(*rest_s) / sample_time_s)))
    return y


def _doublet_plan(n, sample_time_s, null_V, amplitude_V, half_s, rest_s, rng):
    """Doublets (+a then -a) about the null with rests at the null: ``(signal, {first sample: (half, a)})``."""
    rng = np.random.default_rng(rng)
    y = np.full(n, float(null_V))
    starts = {}
    k = int(round(rng.uniform(*rest_s) / sample_time_s))
    while k < n:
        half = max(1, int(round(rng.uniform(*half_s) / sample_time_s)))
        a = rng.choice((-1.0, 1.0)) * rng.uniform(*amplitude_V)
        y[k:k + half] = null_V + a
        y[k + half:k + 2 * half] = null_V - a
        starts[k] = (half, a)
        k += 2 * half + max(1, int(round(rng.uniform(*rest_s) / sample_time_s)))
    return y, starts


def command_doublets(n, sample_time_s, null_V, amplitude_V=(1.5, 3.0), half_s=(0.08, 0.2),
                     rest_s=(0.8, 2.5), rng=None):
    """Open-loop valve command: doublets (+a then -a) about the null, with rests at the null."""
    return _doublet_plan(n, sample_time_s, null_V, amplitude_V, half_s, rest_s, rng)[0]


def _doublet_timing(sample_time_s: float) -> tuple:
    """``(half_s, rest_s)`` of the standard open-loop doublets: shorter on a fast (1 kHz) rig."""
    return ((0.08, 0.2), (0.8, 2.5)) if sample_time_s >= 0.005 else ((0.015, 0.04), (0.2, 0.6))


class Recentering:
    """An open-loop supervisor: at the start of each planned doublet, a piston measured more than ``band_m``
    from mid-stroke gets a single pulse towards the middle instead (the doublet's first half, its amplitude,
    signed towards the middle), as an operator keeps an open-loop test off the end stops.

    Parameters
    ----------
    starts : dict
        ``{first sample of a doublet: (half length in samples, amplitude V)}``.
    null_V, mid_m, band_m : float
    """

    def __init__(self, starts: dict, null_V: float, mid_m: float, band_m: float):
        self.starts, self.null_V, self.mid_m, self.band_m = dict(starts), float(null_V), float(mid_m), float(band_m)
        self._pulse_until, self._pulse_first_half_end, self._pulse_V = -1, -1, 0.0

    def __call__(self, k: int, measured_m: float):
        if k in self.starts and abs(measured_m - self.mid_m) > self.band_m:
            half, amplitude = self.starts[k]
            # a positive command above null extends the piston: push towards the middle
            self._pulse_until = k + 2 * half
            self._pulse_V = self.null_V + (abs(amplitude) if measured_m < self.mid_m else -abs(amplitude))
            self._pulse_first_half_end = k + half
        if k < self._pulse_until:
            return self._pulse_V if k < self._pulse_first_half_end else self.null_V
        return None


def recentering_doublets(rig: Rig, duration_s: float, seed: int = 0, band: float = 0.12) -> Experiment:
    """Open-loop command doublets about the null (as ``standard_experiment(rig, "pulses", loop="open")``) with a
    :class:`Recentering` supervisor: a piston more than ``band`` of the stroke from mid-stroke at the start of
    a doublet gets one pulse towards the middle instead.  The command recorded is what the valve got."""
    ts = rig.sample_time_s
    null = rig.params["valve_null_V"]
    sig, starts = _doublet_plan(int(round(duration_s / ts)), ts, null, (1.5, 3.0), *_doublet_timing(ts), seed)
    supervisor = Recentering(starts, null, 0.5 * rig.stroke_m, band * rig.stroke_m)
    return Experiment("open", ts, sig, None, description="open-loop command doublets, recentred beyond "
                      f"{100 * band:g} % of the stroke from the middle", supervisor=supervisor)


def default_controller(rig: Rig, kp_V_per_m: float | None = None) -> ProportionalController:
    kp = kp_V_per_m if kp_V_per_m is not None else DEFAULT_KP_V_PER_M.get(rig.name, 12.0 / rig.stroke_m)
    return ProportionalController(kp, rig.params["valve_null_V"], rig.params["valve_min_V"], rig.params["valve_max_V"])


#: the longest experiment :func:`standard_experiment` makes, in samples: its recording's dozen arrays of
#: doubles then take about 1 GB (a duration of 1.2e7 s at 1 ms asked numpy for 92 GiB)
MAX_SAMPLES = 10_000_000


def standard_experiment(rig: Rig, kind: str, duration_s: float, loop: str = "closed", seed: int = 0,
                        kp_V_per_m: float | None = None) -> Experiment:
    """The experiments of ``pneusim simulate --input``: ``multisine``, ``steps`` or ``pulses``.

    Closed loop: the signal is a position reference about mid-stroke.  Open
    loop: a valve command about the null (multisine of 0.6 and 0.08 Hz, random
    command steps, or doublets), scaled to the rig so the piston mostly stays in
    its stroke.
    """
    if kind not in INPUT_KINDS:
        raise PneusimError(f"--input must be one of {', '.join(INPUT_KINDS)}, got {kind!r}")
    ts = rig.sample_time_s
    if not (isinstance(duration_s, (int, float)) and 0 < duration_s < float("inf")):
        raise PneusimError(f"--duration must be a finite number of seconds > 0, got {duration_s!r}")
    if duration_s / ts > MAX_SAMPLES + 0.5:
        raise PneusimError(f"--duration {duration_s:g} s gives {duration_s / ts:.4g} samples at {ts} s; at most "
                           f"{MAX_SAMPLES} ({MAX_SAMPLES * ts:g} s) fit in memory as a recording")
    n = int(round(duration_s / ts))
    if n < 50:
        raise PneusimError(f"--duration {duration_s} s gives {n} samples at {ts} s; at least 50 are needed")
    rng = np.random.default_rng(seed)
    t = np.arange(n) * ts
    stroke, null = rig.stroke_m, rig.params["valve_null_V"]
    mid = 0.5 * stroke
    if loop == "closed":
        if kind == "multisine":
            sig = multisine(t, [(0.2 * stroke, 0.6), (0.1 * stroke, 0.08), (0.05 * stroke, 1.3)], mid)
        elif kind == "steps":
            sig = random_steps(n, ts, 0.15 * stroke, 0.85 * stroke, (1.0, 4.0) if ts >= 0.005 else (0.3, 1.5), rng)
        else:
            sig = pulse_train(n, ts, mid, (0.1 * stroke, 0.3 * stroke), (0.02, 0.12), (0.2, 0.8), rng)
        return Experiment("closed", ts, sig, default_controller(rig, kp_V_per_m), description=f"{kind} reference")
    if loop != "open":
        raise PneusimError(f"--loop must be 'open' or 'closed', got {loop!r}")
    if kind == "multisine":
        sig = multisine(t, [(0.04, 0.6), (0.5, 0.08)], null)
    elif kind == "steps":
        sig = null + random_steps(n, ts, -1.0, 1.0, (0.05, 0.3), rng)
    else:
        sig = command_doublets(n, ts, null, (1.5, 3.0), *_doublet_timing(ts), rng)
    return Experiment("open", ts, sig, None, description=f"open-loop {kind} command")
