"""The fit's validation: the fitted model simulated over the validation part, scored with MATLAB's fit %."""

from __future__ import annotations

import numpy as np

from ..metrics import fit_percent
from ..recording import Recording
from ..solver.sensitivity import SensitivitySimulator, command_schedule
from .shooting import position_reading

__all__ = ["validate"]


def validate(model, params, recording: Recording, n_est: int, x0, delay_s: float, stroke_m: float,
             rtol: float) -> dict:
    """Simulate the validation part (samples ``n_est`` on) with the recorded command from the fitted state
    ``x0`` at sample ``n_est - 1``, at the parameter vector ``params`` (SI).

    Returns ``{"t_start_s", "t_end_s", "fit_percent", "states"}``: the part's times, the position's fit %
    (the position as the sensor reads it), the simulated states ``(n_samples - n_est, n)``, and
    ``fit_percent_pressure_a_Pa`` / ``_b_Pa`` where the pressures are recorded.
    """
    sim = SensitivitySimulator(model, [], params, np.zeros(0), stroke_m, rtol)
    start, stop = n_est - 1, recording.n_samples - 1
    schedule = command_schedule(recording.time_s, recording.valve_cmd_V, start, stop, delay_s)
    x, _ = sim.run(recording.time_s[start], x0, schedule, stop - start + 1, False)
    x = x[1:]
    y = recording.position_m[n_est:]
    out = {"t_start_s": float(recording.time_s[n_est]), "t_end_s": float(recording.time_s[-1]),
           "fit_percent": fit_percent(y, position_reading(x[:, 0], stroke_m)), "states": x}
    for name in ("pressure_a_Pa", "pressure_b_Pa"):
        values = getattr(recording, name)
        if values is not None:
            out[f"fit_percent_{name}"] = fit_percent(values[n_est:], x[:, model.state_names.index(name)])
    return out
