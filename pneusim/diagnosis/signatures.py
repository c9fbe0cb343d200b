"""Evidence a user can check: the signatures of ``diagnosis.md`` as numbers.

Every number is computed from the recording and the fitted nominal model's trajectory (the model
driven by the recorded command, its parameters fitted to the recording), never from metadata:

* ``direction_r`` -- correlation of the velocity residual (measured minus model velocity) with the
  direction of motion; ``extend_mean_mm_s`` / ``retract_mean_mm_s`` its mean while extending and
  retracting (friction asymmetry, external load);
* ``pressure_r`` -- correlation of the squared velocity residual with ``|p_A - p_B|`` (with the
  valve opening when pressures were not recorded) (pressure-dependent friction, supply droop);
* ``position_r`` -- correlation of the velocity residual with the position (a spring);
* ``lag_s`` / ``lag_r`` -- lag of the peak of the cross-correlation between command increments
  and residual increments (transport delay, valve dynamics: positive lag);
* ``creep_mm_s`` -- mean speed of the measured piston while the valve is near null and the model
  is at rest, minus the model's (leakage, valve offset);
* ``flat_spot_V`` -- half-width of the command band around null in which the measured piston
  does not move, minus the same band of the model (valve dead band);
* ``small_command_speed_deficit`` -- how much less the small quarter of the off-null commands moves
  the piston than the large quarter, relative to the model (dead band);
* ``null_shift_V`` -- command at which the measured velocity crosses zero (a line through the
  small-command samples), minus the model's (valve offset);
* ``hold_pressure_settling_kPa`` -- how far the pressure residual settles over a hold after a move
  (the valve near null), signed by the move's own pressure change so that the sensor noise averages
  out over holds, in magnitude (heat transfer, leakage), when pressures were recorded;
* ``long_move_r`` -- correlation of the velocity residual's magnitude with the time the valve has
  been wide open (supply droop).
"""

from __future__ import annotations

import math

import numpy as np

from ..model.effects import EFFECTS
from .locate import moving_speed, operating_conditions, valve_null_and_span, velocity_estimate
from .rules import OFF_NULL_V, SMALL_COMMAND_V

__all__ = ["compute_signatures", "evidence_text", "hold_runs", "settling"]


def _corr(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 10:
        return float("nan")
    a, b = a[ok] - a[ok].mean(), b[ok] - b[ok].mean()
    den = math.sqrt(float(np.dot(a, a) * np.dot(b, b)))
    return float(np.dot(a, b) / den) if den > 0 else float("nan")


def _band(u_rel, speed, moving):
    """The smallest commands (5th percentile of |u - null|, within :data:`~.rules.SMALL_COMMAND_V` of null) that
    move the piston."""
    small = np.abs(u_rel) < SMALL_COMMAND_V
    go = small & moving
    if go.sum() < 5:
        return float("nan")
    # the smallest commands that do move the piston
    return float(np.percentile(np.abs(u_rel[go]), 5))


def _lag(u, x, model_position, ok, dt: float) -> tuple[float, float]:
    """``(lag_s, lag_r)``: the lag of the peak of the cross-correlation of command increments with residual
    increments, lags 0 .. 0.2 s, and its correlation (NaN for a constant command or residual)."""
    r = np.where(ok, x - np.nan_to_num(model_position), 0.0)
    du, dr = np.diff(u), np.diff(r)
    max_lag = max(2, min(int(round(0.2 / dt)), du.size // 4))
    if np.std(du) > 0 and np.std(dr) > 0:
        cc = np.array([_corr(du[:du.size - k], dr[k:]) for k in range(max_lag)])
        k_best = int(np.nanargmax(np.abs(cc))) if np.isfinite(cc).any() else 0
        return k_best * dt, float(cc[k_best])
    return float("nan"), float("nan")


def _small_command_speed_deficit(u_rel, v_meas, v_model, ok) -> float:
    """Speed measured / model for the smallest and the largest quarter of the off-null commands: a dead band
    (or a spool that cannot follow) takes more from small commands than from large ones."""
    off = (np.abs(u_rel) > OFF_NULL_V) & ok
    if not off.sum() > 40:
        return float("nan")
    a = np.abs(u_rel[off])
    lo_q, hi_q = np.percentile(a, [25, 75])
    vm, vs = np.abs(v_meas[off]), np.abs(v_model[off])
    small, large = a <= lo_q, a >= hi_q
    ratio_small = vm[small].mean() / max(vs[small].mean(), 1e-12)
    ratio_large = vm[large].mean() / max(vs[large].mean(), 1e-12)
    return float(1.0 - ratio_small / ratio_large) if ratio_large > 0 else float("nan")


def _null_shift(u_rel, v_meas, v_model, ok) -> float:
    """The command at which the measured velocity crosses zero (a line through the small-command samples), minus
    the model's, V."""
    small = (np.abs(u_rel) < SMALL_COMMAND_V) & ok
    if not (small.sum() > 20 and np.ptp(u_rel[small]) > 0):
        return float("nan")
    a_m = np.polyfit(u_rel[small], v_meas[small], 1)
    a_s = np.polyfit(u_rel[small], v_model[small], 1)
    cross_m = -a_m[1] / a_m[0] if a_m[0] != 0 else float("nan")
    cross_s = -a_s[1] / a_s[0] if a_s[0] != 0 else float("nan")
    return float(np.clip(cross_m - cross_s, -5, 5))


def hold_runs(held: np.ndarray, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The holds after moves: ``(since_s, stop, start)``, for each sample of a run of ``held`` samples (N,) bool
    that follows motion, the time since the run began, the index of its first sample and the index where the motion
    before it began (NaN and -1 elsewhere, and on a run the recording starts with)."""
    since, stop, start = np.full(held.size, np.nan), np.full(held.size, -1), np.full(held.size, -1)
    k, moved_from = 0, 0
    while k < held.size:
        if not held[k]:
            k += 1
            continue
        end = k
        while end < held.size and held[end]:
            end += 1
        if k > 0:                                    # a run the recording starts with follows no move
            since[k:end], stop[k:end], start[k:end] = time_s[k:end] - time_s[k], k, moved_from
        k = moved_from = end
    return since, stop, start


def settling(measured: np.ndarray, model: np.ndarray, stop: np.ndarray, start: np.ndarray) -> np.ndarray:
    """The residual's change since each hold began (``stop``, ``start`` of :func:`hold_runs`), signed by the
    measured change over the move before it (N,; meaningful where ``stop >= 0``).  The sign is read from the sample
    before the stop, so that the stop's own noise does not choose it: the sensor noise then averages out over
    holds, and what is left is how the model misses the way the signal settles after a move."""
    residual = measured - model
    return (residual - residual[stop]) * np.sign(measured[stop - 1] - measured[start])


def _hold_pressure_settling(recording, model_states: dict, near_null: np.ndarray) -> float:
    """kPa: how far the pressure residual settles over a hold after a move (the valve near null), in magnitude:
    the mean over holds and both chambers of :func:`settling` over the hold's second half (NaN without holds)."""
    since, stop, start = hold_runs(near_null, recording.time_s)
    settled = [settling(getattr(recording, name), model_states[name], stop, start)
               for name in ("pressure_a_Pa", "pressure_b_Pa")]
    values = []
    for k in np.unique(stop[stop >= 0]):
        run = np.flatnonzero(stop == k)
        if run.size >= 4:
            late = run[since[run] >= 0.5 * since[run[-1]]]
            values += [float(np.nanmean(chamber[late])) for chamber in settled]
    return abs(float(np.nanmean(values))) / 1e3 if values else float("nan")


def compute_signatures(recording, rig, model_states: dict, velocity_model: np.ndarray) -> dict:
    """The signature numbers of the nominal model's residual (see the module docstring).

    Parameters
    ----------
    recording : Recording
    rig : Rig
    model_states : dict
        ``{state name: model value at every sample (N,)}`` of the fitted nominal model.
    velocity_model : ndarray (N,)
        The model's piston velocity, m/s.
    """
    t, x, u = recording.time_s, recording.position_m, recording.valve_cmd_V
    dt = float(t[1] - t[0])
    null, _ = valve_null_and_span(rig)
    v_meas = velocity_estimate(t, x)
    v_model = np.asarray(velocity_model, float)
    e_v = v_meas - velocity_estimate(t, np.nan_to_num(model_states["position_m"], nan=float(np.nanmean(x))))
    ok = np.isfinite(model_states["position_m"])
    masks = operating_conditions(recording, rig, v_meas)
    moving_thr = moving_speed(rig)
    out = {}
    direction = masks["extending"].astype(float) - masks["retracting"]     # +1, -1, 0 while holding still
    out["direction_r"] = _corr(e_v[ok], direction[ok])
    ext, ret = masks["extending"] & ok, masks["retracting"] & ok
    out["extend_mean_mm_s"] = float(np.mean(e_v[ext]) * 1e3) if ext.any() else float("nan")
    out["retract_mean_mm_s"] = float(np.mean(e_v[ret]) * 1e3) if ret.any() else float("nan")
    if recording.has_pressures:
        dp = np.abs(recording.pressure_a_Pa - recording.pressure_b_Pa)
    else:
        dp = np.abs(model_states["pressure_a_Pa"] - model_states["pressure_b_Pa"])
    moving = masks["extending"] | masks["retracting"]
    out["pressure_r"] = _corr((e_v ** 2)[ok & moving], dp[ok & moving])
    out["position_r"] = _corr(e_v[ok], x[ok])
    out["lag_s"], out["lag_r"] = _lag(u, x, model_states["position_m"], ok, dt)
    near_null = masks["valve near null"] & ok
    model_still = np.abs(v_model) < moving_thr
    hold = near_null & model_still
    out["creep_mm_s"] = (float(np.mean(np.abs(v_meas[hold])) - np.mean(np.abs(v_model[hold]))) * 1e3
                         if hold.sum() > 10 else float("nan"))
    u_rel = u - null
    out["flat_spot_V"] = (_band(u_rel, v_meas, moving) - _band(u_rel, v_model, np.abs(v_model) > moving_thr))
    out["small_command_speed_deficit"] = _small_command_speed_deficit(u_rel, v_meas, v_model, ok)
    out["null_shift_V"] = _null_shift(u_rel, v_meas, v_model, ok)
    if recording.has_pressures:
        out["hold_pressure_settling_kPa"] = _hold_pressure_settling(recording, model_states, masks["valve near null"])
    wide = masks["large opening"]
    open_time = np.zeros(t.size)
    for k in range(1, t.size):
        open_time[k] = open_time[k - 1] + dt if wide[k] else 0.0
    out["long_move_r"] = _corr(np.abs(e_v)[ok & wide], open_time[ok & wide]) if (ok & wide).sum() > 10 else float("nan")
    return out


def evidence_text(effect: str, sig: dict) -> str:
    """The signature numbers that bear on ``effect``, in words (the effect's own
    :meth:`~pneusim.model.effects.Effect.evidence`; empty for a name outside the vocabulary)."""
    cls = EFFECTS.get(effect)
    return cls.evidence(sig) if cls is not None else ""
