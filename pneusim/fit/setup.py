"""What every fit of a recording needs before the optimiser runs (:class:`FitSetup`): the checks of the
recording against the rig, the model, the free parameters with their scales and bounds, the starting
values, the measured signals and their noise, and the estimation part; and the shooting problem of a
window of it.  :func:`~pneusim.fit.fit_recording` and :func:`~pneusim.fit.prefit.prefit_recording` build
one each."""

from __future__ import annotations

import numpy as np

from ..errors import FitError
from ..model import ActuatorModel
from ..recording import Recording
from ..rig import Rig, load_rig
from .rules import (DEFAULT_VALIDATION_FRACTION, EXCITATION_NOISE_MULTIPLE, INFORMATIVE_WINDOW, MAX_VALIDATION_FRACTION,
                    MIN_ESTIMATION_SAMPLES, MIN_SEGMENT_SAMPLES, MIN_VALIDATION_SAMPLES, POSITION_NOISE_FLOOR,
                    PRESSURE_NOISE_FLOOR_PA)
from .parameters import DEFAULT_FREE, EFFECT_FREE, SEARCHED, check_free, parameter_bounds, parameter_scale
from .shooting import FitData, ShootingProblem
from .warm_start import check_warm_start, warm_parameters

__all__ = ["FitSetup", "rig_of", "noise_std_estimate", "DEFAULT_VALIDATION_FRACTION", "INFORMATIVE_WINDOW"]


def noise_std_estimate(values: np.ndarray) -> float:
    """Sensor noise from the data: robust std of second differences, ``MAD / 0.6745 / sqrt(6)``.

    The second difference of white noise has variance ``6 sigma^2``; the
    median ignores the samples where the true signal accelerates.
    """
    d2 = np.diff(np.asarray(values, float)[np.isfinite(values)], 2)
    if d2.size < 10:
        return 0.0
    return float(np.median(np.abs(d2 - np.median(d2))) / 0.6745 / np.sqrt(6.0))


class FitSetup:
    """What every fit of a recording needs before the optimiser runs: the checks, the model, the free
    parameters with their scales and bounds, the starting values, the measured signals and their
    noise, and the estimation part; :meth:`problem` builds the shooting problem of a window."""

    def __init__(self, recording: Recording, rig, effects, free, validation_fraction, warm_start, start_values,
                 segment_samples):
        self.recording = recording
        self.rig = rig = _resolve_rig(recording, rig)
        self.model = model = ActuatorModel(effects)
        self.delay_s = model.command_delay_s()
        self.free = free = list(free) if free else _default_free(model)
        check_free(free, model.param_names)
        searched = [name for name in free if name in SEARCHED]
        if searched:
            raise FitError(f"--free {searched[0]}: a transport delay moves the command switch times and has no "
                           "gradient; fix it with --effect transport_delay:delay_s=VALUE and compare the fits over a "
                           "few fixed delays")
        if validation_fraction is None:
            validation_fraction = DEFAULT_VALIDATION_FRACTION
        if not 0.0 < validation_fraction <= MAX_VALIDATION_FRACTION:
            raise FitError(f"validation_fraction must be in (0, {MAX_VALIDATION_FRACTION}], got {validation_fraction}")
        p_nominal = model.param_vector(rig)
        p_start = p_nominal.copy()
        if warm_start is not None:
            p_start = warm_parameters(warm_start, model, p_start)
        for name, value in (start_values or {}).items():
            if name not in model.param_names:
                raise FitError(f"start_values: unknown parameter {name!r}; the model has: "
                               f"{', '.join(model.param_names)}")
            p_start[model.param_names.index(name)] = float(value)
        self.p_start = p_start
        self.index = index = [model.param_names.index(name) for name in free]
        self.scales = np.array([parameter_scale(name, p_nominal[i]) for name, i in zip(free, index)])
        self.bounds = np.array([parameter_bounds(name, p_nominal[i]) for name, i in zip(free, index)])
        self.lower, self.upper = self.bounds[:, 0] / self.scales, self.bounds[:, 1] / self.scales
        self.theta_start = np.clip(p_start[index] / self.scales, self.lower, self.upper)
        self.signals, self.sigma = _signals(recording, rig, model)
        n = recording.n_samples
        self.n_est = n_est = int(round(n * (1.0 - validation_fraction)))
        if n_est < MIN_ESTIMATION_SAMPLES or n - n_est < MIN_VALIDATION_SAMPLES:
            raise FitError(f"{_name(recording)}: {n} samples are too few to fit on {1 - validation_fraction:.0%} and "
                           f"validate on the rest (at least {MIN_ESTIMATION_SAMPLES} estimation and "
                           f"{MIN_VALIDATION_SAMPLES} validation samples)")
        _check_excitation(recording, rig, n_est, self.sigma["position_m"])
        if warm_start is not None:
            check_warm_start(warm_start, recording, n_est)
        self.seg = max(MIN_SEGMENT_SAMPLES, int(segment_samples))

    def window(self, stop: int, start: int = 0) -> FitData:
        """What the fit sees of samples ``start`` to ``stop - 1`` (the noise levels are the whole recording's)."""
        rec = self.recording
        before = float(rec.valve_cmd_V[start - 1 if start > 0 else 0])
        return FitData(rec.time_s[start:stop], rec.valve_cmd_V[start:stop], before,
                       {k: (v[start:stop], self.sigma[k]) for k, v in self.signals.items()})

    def problem(self, stop: int, rtol: float, threads: int, segment: int | None = None, start: int = 0):
        """``(problem, lower, upper)``: the shooting problem of samples ``start`` to ``stop - 1`` (segments of
        ``segment`` samples, default the fit's) and the bounds of its decision variables."""
        pb = ShootingProblem(self.model, self.p_start, self.free, self.scales, self.window(stop, start),
                             self.rig.stroke_m, segment or self.seg, self.delay_s, rtol, threads)
        x_lo, x_hi = pb.state_bounds()
        lo = np.concatenate([self.lower, np.tile(x_lo / pb.x_scale, pb.n_segments)])
        hi = np.concatenate([self.upper, np.tile(x_hi / pb.x_scale, pb.n_segments)])
        return pb, lo, hi

    def prefit_start(self, samples: int) -> int:
        """The first sample of the pre-fit's window of ``samples`` samples: 0, unless the piston moves over less
        than :data:`INFORMATIVE_WINDOW` of the estimation part's position range there; then the start, on a
        segment boundary, of the window over which it moves most (the earliest of equals).

        Why: an open-loop recording can hold the piston at an end stop for seconds before it moves (the
        robustness set's paper-1 open-loop multisines: the first 2000 samples span 0.1-0.2 % of the range).
        A window at rest says nothing about friction and mass: the pre-fit ended at noise there with the
        valve's conductance at 0.52 and the Coulomb friction at 2.1 times the truth, and the whole part's
        fit from it 4.2 times above noise before a second route rescued it.  Every other recording of the
        robustness set and of practice2 spans at least 27 % of the range in its first window and keeps it.
        """
        n_est = self.n_est
        samples = min(int(samples), n_est)
        position = self.recording.position_m[:n_est]

        def span(k):
            part = position[k:k + samples]
            return float(np.nanmax(part) - np.nanmin(part)) if np.isfinite(part).any() else 0.0

        if samples >= n_est or span(0) >= INFORMATIVE_WINDOW * float(np.nanmax(position) - np.nanmin(position)):
            return 0
        candidates = range(0, n_est - samples + 1, self.seg)
        return int(candidates[int(np.argmax([span(k) for k in candidates]))])


def _name(recording: Recording) -> str:
    return str(recording.source or "the recording")


def rig_of(recording: Recording, rig: Rig | str | None = None) -> Rig:
    """``rig`` itself, or loaded by name or file, or else the rig ``recording`` names in its metadata."""
    if rig is None:
        if not recording.rig:
            raise FitError(f"{_name(recording)} names no rig in its metadata ('# rig: ...'); give --rig")
        rig = recording.rig
    return rig if isinstance(rig, Rig) else load_rig(rig)


def _resolve_rig(recording: Recording, rig) -> Rig:
    rig = rig_of(recording, rig)
    # a recording may name another rig than the file given (a user's own copy of a data sheet): the
    # physical checks below decide whether they match, not the names
    if abs(recording.sample_time_s - rig.sample_time_s) > 1e-9 * rig.sample_time_s:
        rig = rig.with_params({"sample_time_s": recording.sample_time_s})
    stroke = rig.stroke_m
    pos = recording.position_m
    if np.nanmin(pos) < -0.01 * stroke or np.nanmax(pos) > 1.01 * stroke:
        raise FitError(f"{_name(recording)}: positions span {np.nanmin(pos) * 1e3:.1f} to {np.nanmax(pos) * 1e3:.1f} mm "
                       f"but rig {rig.name!r} has a stroke of {stroke * 1e3:.1f} mm; is this the right rig?")
    supply = rig.params["supply_Pa"]
    for name in ("pressure_a_Pa", "pressure_b_Pa"):
        values = getattr(recording, name)
        if values is not None and np.nanmax(values) > 1.2 * supply:
            raise FitError(f"{_name(recording)}: {name} reaches {np.nanmax(values) / 1e5:.2f} bar, above rig "
                           f"{rig.name!r}'s supply of {supply / 1e5:.2f} bar (absolute); is this the right rig?")
    return rig


def _default_free(model: ActuatorModel) -> list[str]:
    names = list(DEFAULT_FREE)
    for effect in model.effects:
        names += [n for n in EFFECT_FREE.get(effect.name, ()) if n not in SEARCHED]
    return names


def _signals(recording: Recording, rig: Rig, model: ActuatorModel):
    """Measured signals by state name, and the noise std used to weight each."""
    signals = {"position_m": recording.position_m}
    if recording.has_pressures:
        signals["pressure_a_Pa"] = recording.pressure_a_Pa
        signals["pressure_b_Pa"] = recording.pressure_b_Pa
    sigma = {}
    for name, values in signals.items():
        # the rig file's sensor noise when it states one, else an estimate from the data
        from_rig = float(rig.params.get("position_noise_std_m" if name == "position_m" else "pressure_noise_std_Pa", 0.0))
        floor = rig.stroke_m * POSITION_NOISE_FLOOR if name == "position_m" else PRESSURE_NOISE_FLOOR_PA
        sigma[name] = max(from_rig if from_rig > 0 else noise_std_estimate(values), floor)
    return signals, sigma


def _check_excitation(recording: Recording, rig: Rig, n_est: int, sigma_position: float) -> None:
    pos = recording.position_m[:n_est]
    span = float(np.nanmax(pos) - np.nanmin(pos))
    if span < EXCITATION_NOISE_MULTIPLE * sigma_position:
        raise FitError(f"{_name(recording)}: the piston moves only {span * 1e3:.3f} mm in the estimation part "
                       f"({EXCITATION_NOISE_MULTIPLE * sigma_position * 1e3:.3f} mm needed, {EXCITATION_NOISE_MULTIPLE} "
                       "times the sensor noise); such a recording "
                       "does not excite the friction, mass and valve parameters")
    cmd = recording.valve_cmd_V[:n_est]
    if np.ptp(cmd) == 0.0:
        raise FitError(f"{_name(recording)}: the valve command is constant in the estimation part; "
                       "nothing excites the valve parameters")
