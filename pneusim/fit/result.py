"""The result of a physical parameter fit: estimates, uncertainty, validation, warnings."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..model import ActuatorModel, make_effect
from ..recording import Recording
from ..rig import Rig
from .rules import (ABOVE_NOISE_WARNING, CORRELATION_WARNING, FAR_ABOVE_NOISE, OPEN_DEFECT_WARNING,
                    RELATIVE_STD_WARNING)

__all__ = ["FitResult", "ParameterEstimate", "ABOVE_NOISE_WARNING", "FAR_ABOVE_NOISE"]


@dataclass
class ParameterEstimate:
    """One fitted parameter (SI units, the rig file's name)."""

    name: str
    estimate: float
    std: float
    start: float
    lower: float
    upper: float

    @property
    def relative_std(self) -> float:
        return abs(self.std / self.estimate) if self.estimate != 0 else math.inf

    @property
    def at_bound(self) -> bool:
        span = self.upper - self.lower
        return min(self.estimate - self.lower, self.upper - self.estimate) <= 1e-4 * span

    def to_dict(self) -> dict:
        return {"estimate": self.estimate, "std": _finite(self.std), "start": self.start,
                "bounds": [self.lower, self.upper]}


@dataclass
class FitResult:
    """A fitted physical model.

    Attributes
    ----------
    parameters : dict of ParameterEstimate
        Free parameters by name, with standard errors from the Gauss-Newton
        covariance (each signal weighted by its residual standard deviation).
    correlation : ndarray (n_free, n_free)
        Correlation matrix of the estimates, ``free`` order.
    rig_ : Rig
        The rig with the fitted rig parameters.
    effects_ : list of Effect
        The effects with their fitted parameters.
    validation : dict
        ``t_start_s``, ``t_end_s``, ``fit_percent`` (position, MATLAB compare fit
        of the simulation with the recorded command on the validation part,
        which the fit never saw), and the pressures' fits when recorded.
    warnings : list of str
        Parameters the recording does not pin down (huge variance, correlation
        above 0.99, at a bound).
    solver : dict
        How the fit went: ``success`` is the verdict, ``converged_to_noise`` (what the fit reached, whichever
        optimiser finished it and however it stopped); ``stopped_by`` says in words how the last optimiser
        stopped (Gauss-Newton settling, or IPOPT's status, iterations and formulation), ``status``,
        ``ipopt_success``, ``iterations`` and ``formulation`` the same as fields; ``seconds`` and
        ``cpu_seconds`` the fit's wall-clock and processor time; the stages' path (``prefit_attempts``,
        ``tracked_route``, ``prediction_error_route``).
    noise_std : dict
        Sensor noise std the residuals were divided by, per measured signal (SI units).
    normalised_residuals : dict
        Residual rms over noise std per measured signal (1 at the noise level).
    normalised_residual : float
        The largest of ``normalised_residuals``.
    converged_to_noise : bool
        ``normalised_residual <= ABOVE_NOISE_WARNING`` (1.1); when False, ``warnings`` says so.
    """

    recording_name: str
    rig: Rig
    rig_: Rig
    model: ActuatorModel
    effects_: list
    free: list
    parameters: dict
    correlation: np.ndarray
    params_vector: np.ndarray
    n_estimation: int
    sigma: dict
    validation: dict
    solver: dict
    warnings: list = field(default_factory=list)
    recording: Recording | None = None
    estimation_states: np.ndarray | None = None
    noise_std: dict = field(default_factory=dict)

    @classmethod
    def build(cls, *, recording: Recording, rig: Rig, model: ActuatorModel, free, parameters, correlation,
              params_vector, n_estimation, sigma, validation, solver, estimation_states, noise_std=None):
        rig_updates = {k: p.estimate for k, p in parameters.items() if k in rig.params}
        effects = []
        for effect in model.effects:
            values = dict(effect.values)
            for key in values:
                qualified = f"{effect.name}.{key}"
                if qualified in parameters:
                    values[key] = parameters[qualified].estimate
            effects.append(make_effect(effect.name, **effect.option_values, **values))
        result = cls(recording_name=str(recording.source or "recording"), rig=rig, rig_=rig.with_params(rig_updates),
                     model=model, effects_=effects, free=list(free), parameters=parameters,
                     correlation=np.asarray(correlation), params_vector=np.asarray(params_vector),
                     n_estimation=n_estimation, sigma=sigma, validation=validation,
                     solver=solver, recording=recording, estimation_states=estimation_states,
                     noise_std=dict(noise_std or {}))
        # the verdict is what the fit reached, not how its last optimiser stopped (that is solver["stopped_by"])
        result.solver["success"] = result.converged_to_noise
        result.warnings = result._noise_warnings() + result._continuity_warnings() + result._identifiability_warnings()
        return result

    # ----------------------------------------------------------------- access
    def trajectory(self) -> np.ndarray:
        """The fitted model at every sample of the recording, ``(n_samples, n_states)`` in SI units:
        the estimation part's fitted trajectory (segment by segment), then the free simulation over
        the validation part, with the position as the sensor reads it (within ``0 .. stroke``, see
        :func:`.shooting.position_reading`).  NaN where there is nothing (no estimation states)."""
        from .shooting import position_reading

        X = np.full((self.recording.n_samples, len(self.model.state_names)), np.nan)
        if self.estimation_states is not None:
            X[:self.n_estimation] = self.estimation_states[:self.n_estimation]
        X[self.n_estimation:] = self.validation["states"]
        i = self.model.state_names.index("position_m")
        X[:, i] = position_reading(X[:, i], self.rig.stroke_m)   # NaN stays NaN
        return X

    @property
    def estimates(self) -> dict[str, float]:
        """``{name: fitted value}`` in SI units."""
        return {k: p.estimate for k, p in self.parameters.items()}

    @property
    def fit_percent(self) -> float:
        """Validation fit of the position, %."""
        return float(self.validation["fit_percent"])

    @property
    def normalised_residuals(self) -> dict[str, float]:
        """Residual rms divided by the sensor noise std, per measured signal (1 = noise level)."""
        return {k: float(self.sigma[k] / self.noise_std[k]) for k in self.sigma if self.noise_std.get(k, 0) > 0}

    @property
    def normalised_residual(self) -> float:
        """The largest per-signal residual rms over noise std (1 = noise level)."""
        values = self.normalised_residuals.values()
        return float(max(values)) if values else float("nan")

    @property
    def converged_to_noise(self) -> bool:
        """Whether every measured signal's residual is within ``ABOVE_NOISE_WARNING`` of its noise."""
        return bool(math.isfinite(self.normalised_residual) and self.normalised_residual <= ABOVE_NOISE_WARNING)

    def _noise_warnings(self) -> list[str]:
        if self.converged_to_noise:
            return []
        parts = ", ".join(f"{k} {v:.2f}" for k, v in self.normalised_residuals.items())
        return [f"the fit ends above the sensor noise (residual rms / noise std: {parts}; above "
                f"{ABOVE_NOISE_WARNING} means the model does not explain the recording down to noise: a missing "
                "effect, a wrong rig file, a friction smoothing velocity unlike the rig file's (try freeing "
                "friction_smoothing_velocity_m_per_s), or a fit stuck in a local minimum)"]

    def _continuity_warnings(self) -> list[str]:
        defect = float(self.solver.get("max_defect", 0.0) or 0.0)
        if not defect > OPEN_DEFECT_WARNING:
            return []
        return [f"the fitted trajectory is not continuous: a shooting segment ends up to {defect:.3g} (in units of "
                "the state scales: stroke, 1 m/s, 1 bar) away from where the next one starts, so the residual is "
                "lower than a continuous simulation of the fitted model gives (the optimiser ended in its penalty "
                f"form; {self.solver.get('formulation', '')})"]

    def _identifiability_warnings(self) -> list[str]:
        out = []
        for name, p in self.parameters.items():
            if not math.isfinite(p.std):
                out.append(f"{name} is not identifiable from this recording (the data leave it unconstrained)")
            elif p.relative_std > RELATIVE_STD_WARNING:
                out.append(f"{name} is poorly determined: standard error {p.relative_std:.0%} of its value")
            if p.at_bound:
                out.append(f"{name} = {p.estimate:.4g} sits at its bound [{p.lower:.4g}, {p.upper:.4g}]: "
                           "the data push it beyond the physical range")
        names = self.free
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                r = self.correlation[i, j]
                if np.isfinite(r) and abs(r) > CORRELATION_WARNING:
                    out.append(f"{names[i]} and {names[j]} are correlated (r = {r:+.3f}): this recording "
                               "cannot tell them apart")
        return out

    # ------------------------------------------------------------------ output
    def to_dict(self) -> dict:
        """The JSON result (``parameters``, ``correlation``, ``validation``, ``solver``, ``warnings`` ...)."""
        validation = {k: _finite(v) for k, v in self.validation.items() if not isinstance(v, np.ndarray)}
        solver = {k: _finite(v) for k, v in self.solver.items() if k != "prefit_attempts"}
        solver["prefit_attempts"] = [{k: (v.tolist() if isinstance(v, np.ndarray) else _finite(v))
                                      for k, v in a.items() if k != "theta"}
                                     for a in self.solver.get("prefit_attempts", [])]
        return {
            "recording": self.recording_name,
            "rig": self.rig.name,
            "effects": [e.to_text() for e in self.effects_],
            "parameters": {k: p.to_dict() for k, p in self.parameters.items()},
            "correlation": {"names": list(self.free),
                            "matrix": [[_finite(float(v)) for v in row] for row in self.correlation]},
            "noise_std": {k: float(v) for k, v in self.sigma.items()},
            "sensor_noise_std": {k: float(v) for k, v in self.noise_std.items()},
            "normalised_residual": _finite(self.normalised_residual),
            "normalised_residuals": {k: _finite(v) for k, v in self.normalised_residuals.items()},
            "converged_to_noise": self.converged_to_noise,
            "success": bool(self.solver.get("success", False)),
            "estimation": {"t_start_s": float(self.recording.time_s[0]) if self.recording is not None else 0.0,
                           "t_end_s": float(self.recording.time_s[self.n_estimation - 1])
                           if self.recording is not None else None,
                           "samples": int(self.n_estimation)},
            "validation": validation,
            "solver": solver,
            "warnings": list(self.warnings),
        }

    def write_json(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    def summary(self) -> str:
        """A table of the estimates for the terminal."""
        lines = [f"{'parameter':<44} {'start':>11} {'estimate':>11} {'std':>10}"]
        for name, p in self.parameters.items():
            std = f"{p.std:.3g}" if math.isfinite(p.std) else "inf"
            lines.append(f"{name:<44} {p.start:>11.4g} {p.estimate:>11.4g} {std:>10}")
        v = self.validation
        lines.append(f"validation {v['t_start_s']:.3f}-{v['t_end_s']:.3f} s: fit {v['fit_percent']:.2f} % (position)")
        lines.append(f"finished by: {self.solver.get('stopped_by', self.solver['status'])}; "
                     f"{self.solver['seconds']:.1f} s in all")
        lines.append(f"normalised residual (rms / sensor noise): {self.normalised_residual:.3f}"
                     + ("" if self.converged_to_noise else f" -- above noise (> {ABOVE_NOISE_WARNING})"))
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _finite(value):
    """``value`` with every non-finite float (in lists and dicts too) as None: JSON has no infinity."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value
