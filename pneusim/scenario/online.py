"""Online identification in a scenario: the simulated rig run with the estimators inside the loop.

:func:`simulate_online` steps a :class:`~pneusim.plant.SimulatedPlant` through the shared sample loop
(:func:`pneusim.loop.run_loop`, as fast as possible) and, at every sample, first lets each estimator
(:mod:`pneusim.online`) predict and update on the new measurement, then lets the controller act: the
estimators run inside the loop on exactly the data the loop produces, never on a stored record.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import PneusimError
from ..experiment import Experiment
from ..loop import StatusLine, run_loop
from ..online import PaperRLS
from ..plant import SimulatedPlant
from ..recording import Recording
from ..rig import Rig
from ..version import __version__

__all__ = ["simulate_online", "OnlineResult"]


@dataclass
class OnlineResult:
    """What :func:`simulate_online` returns.

    Attributes
    ----------
    recording : Recording
    predictions : dict
        ``{(estimator name, h): ndarray (N,)}``, output units, NaN where undefined.
    thetas : dict
        ``{estimator name: ndarray (N, 2n)}``, theta after each sample.
    wall_time_s : float
    """

    recording: Recording
    predictions: dict = field(default_factory=dict)
    thetas: dict = field(default_factory=dict)
    wall_time_s: float = 0.0


def simulate_online(rig: Rig, experiment: Experiment, estimators: dict[str, PaperRLS],
                    to_output: Callable[[float], float], to_input: Callable[[float, int], float],
                    effects=(), *, seed: int = 0, noise_scale: float = 1.0, progress: bool = False) -> OnlineResult:
    """Run ``experiment`` with the estimators inside the loop.

    Parameters
    ----------
    estimators : {name: PaperRLS}
    to_output : callable(position_m) -> y
        Measured position (m) to the estimators' output unit.
    to_input : callable(command_V, k) -> u
        Applied command (V) and sample index to the estimators' input.
    """
    if experiment.sample_time_s != rig.sample_time_s:
        rig = rig.with_params({"sample_time_s": experiment.sample_time_s})
    plant = SimulatedPlant(rig, effects, seed=seed, noise_scale=noise_scale)
    ts, n, closed = experiment.sample_time_s, experiment.n_samples, experiment.loop == "closed"
    ctrl = experiment.controller
    first = experiment.signal[0]
    x0 = experiment.initial_position_m
    if x0 is None:
        x0 = float(np.clip(first, 0.0, rig.stroke_m)) if closed else 0.5 * rig.stroke_m
    n_warm = int(round(experiment.warmup_s / ts))
    plant.reset(x0, ctrl.command(-n_warm * ts, first, x0) if closed else first, t0_s=-n_warm * ts)
    # the sample loop of the mixed-reality environment, here as fast as possible (no pacing)
    res = run_loop(plant, experiment.signal, ctrl if closed else None, estimators, to_output, to_input,
                   n_warm=n_warm, status=StatusLine(interval_s=0.5, label="online run") if progress else None)
    if not res.completed:          # a fault, or the Ctrl-C / SIGTERM that stopped the loop: raised again here
        raise res.exception if res.exception is not None else PneusimError(res.error or res.stop_reason)
    pos, cmd, pa, pb = res.position_m, res.valve_cmd_V, res.pressure_a_Pa, res.pressure_b_Pa
    preds, thetas, wall = res.predictions, res.thetas, res.wall_time_s
    meta = {"format": "pneusim-recording/1", "sample_time_s": repr(ts), "rig": rig.name, "loop": experiment.loop,
            "description": experiment.description or "online identification run",
            "generator": f"pneusim {__version__}", "seed": str(seed),
            "effects": ";".join(repr(e) for e in plant.model.effects) or "none"}
    if closed:
        meta.update(ctrl.metadata())
    rec = Recording(time_s=np.arange(n) * ts, valve_cmd_V=cmd, position_m=pos,
                    reference_m=experiment.signal.copy() if closed else None,
                    pressure_a_Pa=pa, pressure_b_Pa=pb, metadata=meta)
    return OnlineResult(rec, preds, thetas, wall)
