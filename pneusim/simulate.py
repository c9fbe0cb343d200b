"""Run an experiment on a simulated rig and get a recording (plus the true states).

``simulate(rig, experiment)`` steps a :class:`~pneusim.plant.SimulatedPlant`
sample by sample: measure, let the controller (closed loop) or the signal
(open loop) choose the command, hold it for one sample.  The warm-up before
``t = 0`` holds the first sample so that the recording starts from a settled
rig, as the practice recordings do.

With the built-in parts (CVODE, :class:`~pneusim.sensors.Sensors`, open loop or
exactly a :class:`~pneusim.controller.ProportionalController`) the same loop
runs in C (:meth:`SimulatedPlant.compiled_loop`), with the same results to the
last bit; any other controller or backend runs in the Python loop below.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from . import __version__
from .errors import PneusimError
from .experiment import Experiment
from .model import ActuatorModel, Effect
from .plant import SimulatedPlant
from .recording import Recording
from .rig import Rig

__all__ = ["Simulation", "simulate", "rerun_recording"]

#: run the sample loop in C when the plant, sensors and controller are the built-in ones
#: (:meth:`SimulatedPlant.compiled_loop`); False forces the Python loop (tests compare the two)
COMPILED_LOOP = True


@dataclass
class Simulation:
    """Result of :func:`simulate`.

    Attributes
    ----------
    recording : Recording
        What the sensors read (``pneusim-recording/1`` columns and metadata).
    states : ndarray, shape (N, n_states)
        True states at the sample instants, ``state_names`` order.
    commands_V : ndarray, shape (N,)
        Commands sent at the sample instants.
    wall_time_s : float
    solver_stats : dict
    """

    recording: Recording
    states: np.ndarray
    state_names: tuple
    model: ActuatorModel
    params: np.ndarray
    wall_time_s: float
    solver_stats: dict = field(default_factory=dict)

    def state(self, name: str) -> np.ndarray:
        return self.states[:, self.state_names.index(name)]


def simulate(rig: Rig, experiment: Experiment, effects: Sequence[Effect] = (), *, seed: int = 0,
             backend: str = "cvode", rtol: float = 1e-6, noise_scale: float = 1.0,
             record_pressures: bool = True, model: ActuatorModel | None = None,
             progress: bool = False) -> Simulation:
    """Simulate ``experiment`` on ``rig`` with ``effects`` switched on.

    Parameters
    ----------
    rig, experiment, effects:
        What is simulated.  ``experiment.sample_time_s`` overrides the rig's.
    seed : int
        Seed of the sensor noise (the experiment's own randomness is in its signal).
    backend : str
        ``cvode`` or a SciPy reference backend.
    rtol : float
        Relative tolerance of the ODE solver.
    noise_scale : float
        Multiplies the rig's sensor noise (0: noise-free, still quantised).
    record_pressures : bool
        Whether the recording holds ``pressure_a_Pa`` and ``pressure_b_Pa``.
    """
    if not (isinstance(noise_scale, (int, float)) and noise_scale >= 0 and np.isfinite(noise_scale)):
        raise PneusimError(f"noise_scale must be a finite number >= 0, got {noise_scale!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise PneusimError(f"seed must be a whole number >= 0, got {seed!r}")
    if experiment.sample_time_s != rig.sample_time_s:
        rig = rig.with_params({"sample_time_s": experiment.sample_time_s})
    plant = SimulatedPlant(rig, effects, backend=backend, rtol=rtol, seed=seed, noise_scale=noise_scale,
                           model=model)
    ts = experiment.sample_time_s
    n = experiment.n_samples
    closed = experiment.loop == "closed"
    controller = experiment.controller
    if controller is not None:
        controller.reset()
    first = experiment.signal[0]
    if experiment.initial_position_m is not None:
        x_init = experiment.initial_position_m
    else:
        x_init = float(np.clip(first, 0.0, rig.stroke_m)) if closed else 0.5 * rig.stroke_m
    n_warm = int(round(experiment.warmup_s / ts))
    u_first = controller.command(-n_warm * ts, first, x_init) if closed else first
    plant.reset(x_init, u_first, t0_s=-n_warm * ts, pressures_Pa=experiment.initial_pressures_Pa)

    n_states = len(plant.model.state_names)
    positions, commands = np.empty(n), np.empty(n)
    pa, pb = np.empty(n), np.empty(n)
    states = np.empty((n, n_states))
    started = time.perf_counter()
    supervisor = experiment.supervisor
    # the compiled loop knows the built-in controller and planned commands; a supervisor runs in Python
    loop = plant.compiled_loop(controller if closed else None) if COMPILED_LOOP and supervisor is None else None
    if loop is not None:
        # the same loop in C (built-in sensors, proportional controller or open loop, CVODE)
        signal = np.ascontiguousarray(experiment.signal, dtype=float)
        bounds = list(range(-n_warm, n, 2000 if progress else n + n_warm)) + [n]
        bar = None
        if progress:
            from tqdm import tqdm
            bar = tqdm(total=n + n_warm, desc="simulate", unit="sample", leave=False, mininterval=0.5)
        for k_from, k_to in zip(bounds[:-1], bounds[1:]):  # in chunks only to move the progress bar
            normals = plant.sensors.take_normals((k_to - k_from) * loop.normals_per_sample)
            flag, t_reached, message = loop.run(k_from, k_to, n, signal, normals, positions, commands, pa, pb,
                                                states)
            if flag < 0:
                plant.solver.failed(flag, t_reached, message)
            if bar is not None:
                bar.update(k_to - k_from)
        if bar is not None:
            bar.close()
        plant.sync_from(loop)
    else:
        steps = range(-n_warm, n)
        if progress:
            from tqdm import tqdm
            steps = tqdm(steps, desc="simulate", unit="sample", leave=False, mininterval=0.5)
        for k in steps:
            reading = plant.measure()
            ref = experiment.signal[max(k, 0)]
            u = controller.command(reading.t_s, ref, reading.position_m) if closed else ref
            if supervisor is not None and k >= 0:
                override = supervisor(k, reading.position_m)
                u = ref if override is None else override
            if k >= 0:
                positions[k], commands[k] = reading.position_m, u
                pa[k], pb[k] = reading.pressure_a_Pa, reading.pressure_b_Pa
                states[k] = plant.state
                if k == n - 1:
                    break
            plant.step(u)
    wall = time.perf_counter() - started

    meta = {"format": "pneusim-recording/1", "sample_time_s": repr(ts), "rig": rig.name,
            "loop": experiment.loop}
    if closed:
        meta.update(controller.metadata())
    meta["description"] = experiment.description or "simulated by pneusim"
    meta["generator"] = f"pneusim {__version__}"
    meta["seed"] = str(seed)
    meta["effects"] = ";".join(e.to_text() for e in plant.model.effects) or "none"
    # provenance: with these a run can be repeated (pneusim simulate --like reads them back)
    meta["noise_scale"] = repr(float(noise_scale))
    overrides = {k: v for k, v in getattr(rig, "overrides", {}).items() if k != "sample_time_s"}
    meta["rig_overrides"] = ";".join(f"{k}={float(v)!r}" for k, v in sorted(overrides.items())) or "none"
    if rig.source and not getattr(rig, "is_shipped", True):
        meta["rig_file"] = str(Path(rig.source).resolve())   # --like finds it from any folder
    meta.update({k: str(v) for k, v in experiment.metadata.items()})
    recording = Recording(
        time_s=np.arange(n) * ts, valve_cmd_V=commands, position_m=positions,
        reference_m=experiment.signal.copy() if closed else None,
        pressure_a_Pa=pa if record_pressures else None, pressure_b_Pa=pb if record_pressures else None,
        metadata=meta)
    return Simulation(recording, states, plant.model.state_names, plant.model, plant.params, wall,
                      plant.solver.stats)


def rerun_recording(rig: Rig, recording: Recording, effects: Sequence[Effect] = (), **options) -> Simulation:
    """Re-run the experiment of a recording: its commands (open loop) or reference and controller (closed)."""
    from .controller import controller_from_metadata

    pressures = None
    if recording.has_pressures and np.isfinite(recording.pressure_a_Pa[0]) and np.isfinite(recording.pressure_b_Pa[0]):
        pressures = (float(recording.pressure_a_Pa[0]), float(recording.pressure_b_Pa[0]))
    if recording.loop == "closed":
        controller = controller_from_metadata(recording.metadata, where=str(recording.source or "recording"))
        exp = Experiment("closed", recording.sample_time_s, recording.reference_m, controller,
                         initial_position_m=float(recording.position_m[0]), initial_pressures_Pa=pressures,
                         description=f"re-run of {recording.source or 'a recording'}")
    else:
        exp = Experiment("open", recording.sample_time_s, recording.valve_cmd_V, None,
                         initial_position_m=float(recording.position_m[0]), initial_pressures_Pa=pressures,
                         description=f"re-run of {recording.source or 'a recording'}")
    options.setdefault("record_pressures", recording.has_pressures)
    return simulate(rig, exp, effects, **options)
