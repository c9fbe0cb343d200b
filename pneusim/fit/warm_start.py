"""Starting a fit from an earlier fit of the same recording (``fit_recording(..., warm_start=fit)``).

Diagnosis refits a recording once per candidate effect; each refit starts from the nominal fit's
parameters and its states at every estimation sample instead of running the pre-fit again.
"""

from __future__ import annotations

import numpy as np

from ..errors import FitError
from ..model import ActuatorModel
from ..recording import Recording
from .result import FitResult
from .shooting import ShootingProblem

__all__ = ["check_warm_start", "warm_parameters", "warm_states"]


def check_warm_start(warm: FitResult, recording: Recording, n_est: int) -> None:
    """Refuse a warm start that is not a fit of ``recording`` with the same estimation part."""
    other = warm.recording
    same = (other is not None and other.n_samples == recording.n_samples and warm.n_estimation == n_est
            and np.array_equal(other.valve_cmd_V, recording.valve_cmd_V))
    if not same or warm.estimation_states is None:
        raise FitError(f"{recording.source or 'the recording'}: warm_start must be a fit of this recording with the same "
                       f"validation fraction ({n_est} estimation samples)")


def warm_parameters(warm: FitResult, model: ActuatorModel, p_start: np.ndarray) -> np.ndarray:
    """``p_start`` with every parameter the warm fit's model has replaced by its fitted value."""
    p = p_start.copy()
    fitted = dict(zip(warm.model.param_names, np.asarray(warm.params_vector, float)))
    for i, name in enumerate(model.param_names):
        if name in fitted:
            p[i] = fitted[name]
    return p


def warm_states(warm: FitResult, pb: ShootingProblem, params: np.ndarray, recording: Recording) -> np.ndarray:
    """Segment start states from the warm fit's states at every estimation sample; the states its
    model lacks from this model's equilibrium at that sample's position and command."""
    model = pb.model
    values = dict(zip(model.param_names, params))
    shared = [(i, warm.model.state_names.index(s)) for i, s in enumerate(model.state_names)
              if s in warm.model.state_names]
    x_lo, x_hi = pb.state_bounds()
    out = np.zeros((pb.n_segments, pb.n))
    for j, k in enumerate(pb.starts):
        old = warm.estimation_states[k]
        x = model.initial_state(None, float(old[0]), float(recording.valve_cmd_V[k]), params=values,
                                pressures_Pa=(float(old[2]), float(old[3])))
        for i, i_old in shared:
            x[i] = old[i_old]
        out[j] = np.clip(x, x_lo, x_hi)
    return out
