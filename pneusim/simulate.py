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

:func:`rig_effects` builds the effects a rig file's ``[effects.NAME]`` tables switch on, and
:func:`merged_effects` adds a scenario's own to them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .controller import controller_from_metadata
from .errors import InputFileError, PneusimError
from .experiment import Experiment
from .model import ActuatorModel, Effect, parse_effect_text
from .plant import SimulatedPlant
from .plausibility import rig_file_sha256
from .recording import Recording
from .rig import Rig
from .version import __version__

__all__ = ["Simulation", "simulate", "rerun_recording", "rig_effects", "merged_effects"]

#: samples the compiled loop runs between two updates of a progress bar
PROGRESS_CHUNK = 2000


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
             progress: bool = False, compiled: bool = True, solver_options: Mapping | None = None) -> Simulation:
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
    compiled : bool
        Run the sample loop in C when the plant, sensors and controller are the built-in ones
        (:meth:`SimulatedPlant.compiled_loop`); False forces the Python loop (the same results).
    solver_options : mapping or None
        Further options of the ODE backend (e.g. ``max_steps`` between two samples).
    """
    _check_run_options(noise_scale, seed)
    if experiment.sample_time_s != rig.sample_time_s:
        rig = rig.with_params({"sample_time_s": experiment.sample_time_s})
    plant = SimulatedPlant(rig, effects, backend=backend, rtol=rtol, seed=seed, noise_scale=noise_scale,
                           model=model, solver_options=solver_options)
    n_warm = _rest_before_warmup(plant, rig, experiment)
    trace = _Trace.empty(experiment.n_samples, len(plant.model.state_names))
    started = time.perf_counter()
    closed = experiment.loop == "closed"
    # the compiled loop knows the built-in controller and planned commands; a supervisor runs in Python
    loop = (plant.compiled_loop(experiment.controller if closed else None)
            if compiled and experiment.supervisor is None else None)
    if loop is not None:
        _run_compiled(plant, loop, experiment, n_warm, trace, progress)
    else:
        _run_python(plant, experiment, n_warm, trace, progress)
    wall = time.perf_counter() - started
    ts, n = experiment.sample_time_s, experiment.n_samples
    recording = Recording(
        time_s=np.arange(n) * ts, valve_cmd_V=trace.commands_V, position_m=trace.positions_m,
        reference_m=experiment.signal.copy() if closed else None,
        pressure_a_Pa=trace.pressure_a_Pa if record_pressures else None,
        pressure_b_Pa=trace.pressure_b_Pa if record_pressures else None,
        metadata=_metadata(rig, experiment, plant, seed, noise_scale))
    return Simulation(recording, trace.states, plant.model.state_names, plant.model, plant.params, wall,
                      plant.solver.stats)


@dataclass
class _Trace:
    """What one run records, one row per sample (filled by the loop)."""

    positions_m: np.ndarray
    commands_V: np.ndarray
    pressure_a_Pa: np.ndarray
    pressure_b_Pa: np.ndarray
    states: np.ndarray

    @classmethod
    def empty(cls, n: int, n_states: int) -> "_Trace":
        return cls(np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty((n, n_states)))


def _check_run_options(noise_scale, seed) -> None:
    if not (isinstance(noise_scale, (int, float)) and noise_scale >= 0 and np.isfinite(noise_scale)):
        raise PneusimError(f"noise_scale must be a finite number >= 0, got {noise_scale!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise PneusimError(f"seed must be a whole number >= 0, got {seed!r}")


def _rest_before_warmup(plant: SimulatedPlant, rig: Rig, experiment: Experiment) -> int:
    """Reset the controller and put the plant at rest where the warm-up starts; returns its sample count.

    The piston rests at ``experiment.initial_position_m``, else at the first reference (closed
    loop, within the stroke) or mid-stroke (open loop), with the first command already applied.
    """
    ts = experiment.sample_time_s
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
    return n_warm


def _progress_bar(total: int):
    from .progress import progress_bar   # a bar on a terminal, lines in a log

    return progress_bar(total, desc="simulate", unit="sample", leave=False, mininterval=0.5)


def _run_compiled(plant: SimulatedPlant, loop, experiment: Experiment, n_warm: int, trace: _Trace,
                  progress: bool) -> None:
    """The sample loop in C (built-in sensors, proportional controller or open loop, CVODE), in chunks
    only to move the progress bar."""
    n = experiment.n_samples
    signal = np.ascontiguousarray(experiment.signal, dtype=float)
    bounds = list(range(-n_warm, n, PROGRESS_CHUNK if progress else n + n_warm)) + [n]
    bar = _progress_bar(n + n_warm) if progress else None
    for k_from, k_to in zip(bounds[:-1], bounds[1:]):
        normals = plant.sensors.take_normals((k_to - k_from) * loop.normals_per_sample)
        flag, t_reached, message = loop.run(k_from, k_to, n, signal, normals, trace.positions_m, trace.commands_V,
                                            trace.pressure_a_Pa, trace.pressure_b_Pa, trace.states)
        if flag < 0:
            plant.solver.failed(flag, t_reached, message)
        if bar is not None:
            bar.update(k_to - k_from)
    if bar is not None:
        bar.close()
    plant.sync_from(loop)


def _run_python(plant: SimulatedPlant, experiment: Experiment, n_warm: int, trace: _Trace, progress: bool) -> None:
    """The sample loop in Python: measure, choose the command (controller, plan or supervisor), record, step."""
    n = experiment.n_samples
    closed = experiment.loop == "closed"
    controller, supervisor = experiment.controller, experiment.supervisor
    bar = _progress_bar(n + n_warm) if progress else None
    for k in range(-n_warm, n):
        reading = plant.measure()
        ref = experiment.signal[max(k, 0)]
        u = controller.command(reading.t_s, ref, reading.position_m) if closed else ref
        if supervisor is not None and k >= 0:
            override = supervisor(k, reading.position_m)
            u = ref if override is None else override
        if k >= 0:
            trace.positions_m[k], trace.commands_V[k] = reading.position_m, u
            trace.pressure_a_Pa[k], trace.pressure_b_Pa[k] = reading.pressure_a_Pa, reading.pressure_b_Pa
            trace.states[k] = plant.state
            if k == n - 1:
                break
        plant.step(u)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()


def _metadata(rig: Rig, experiment: Experiment, plant: SimulatedPlant, seed: int, noise_scale: float) -> dict:
    """The recording's metadata: format, rig, loop and controller, and what repeats the run."""
    closed = experiment.loop == "closed"
    meta = {"format": "pneusim-recording/1", "sample_time_s": repr(experiment.sample_time_s), "rig": rig.name,
            "loop": experiment.loop}
    if closed:
        meta.update(experiment.controller.metadata())
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
        if Path(rig.source).is_file():   # and knows whether it changed since (pneusim.plausibility.recording_rig)
            meta["rig_file_sha256"] = rig_file_sha256(rig.source)
    meta.update({k: str(v) for k, v in experiment.metadata.items()})
    return meta


def rerun_recording(rig: Rig, recording: Recording, effects: Sequence[Effect] = (), **options) -> Simulation:
    """Re-run the experiment of a recording: its commands (open loop) or reference and controller (closed)."""
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


def rig_effects(rig: Rig) -> list[Effect]:
    """The effects of the rig file's ``[effects.NAME]`` tables (``rig.effects``), built.

    Raises
    ------
    InputFileError
        An unknown effect, parameter or value, naming the rig file and ``effects.NAME``.
    """
    out = []
    for text in getattr(rig, "effects", ()):
        try:
            out.append(parse_effect_text(text))
        except PneusimError as exc:
            raise InputFileError(str(exc), path=rig.source or rig.name, field=f"effects.{text.partition(':')[0]}") \
                from None
    return out


def merged_effects(rig: Rig, texts: Sequence[str]) -> list[Effect]:
    """The rig's own effects (a rig variant's ``[effects]``) plus those of ``texts``
    (``NAME:PARAM=VALUE,...``); an effect of ``texts`` replaces the rig's effect of the same name."""
    own = [parse_effect_text(t) for t in texts]
    names = {e.name for e in own}
    return [e for e in rig_effects(rig) if e.name not in names] + own
