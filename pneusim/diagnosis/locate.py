"""Locate the mismatch: stretches where the nominal model's residual exceeds the sensor noise.

The residual of each measured signal (position, and both chamber pressures when recorded) is
divided by that sensor's noise standard deviation, estimated from the data's second differences
(:func:`pneusim.fit.noise_std_estimate`).  Its mean square over a sliding window of ``m`` samples
is ``chi^2_m / m`` for pure noise; a window is flagged when it exceeds the chi-square quantile at a
false-alarm probability of ``alpha / (number of windows)`` (``alpha`` = :data:`~.rules.FALSE_ALARM`,
Bonferroni over the recording), so a recording explained up to noise gives no window.  Neighbouring
flagged windows are merged and each stretch is tagged with the operating condition during it, computed
from the recording alone.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from .result import MismatchWindow
from .rules import (CONDITION_SHARE, END_STOP_STROKE, EPISODE_GAP, EPISODE_LENGTH, FALSE_ALARM, FAST_CHANGE_S,
                    FAST_CHANGE_SPAN, HIGH_PRESSURE_SUPPLY, LARGE_OPENING_HALF_SPAN, LOCATE_WINDOW_S,
                    LOCATE_WINDOW_SAMPLES, LOW_PRESSURE_ATMOSPHERES, MAX_EPISODES, MAX_WINDOWS, MOVING_STROKE,
                    NEAR_NULL_SPAN, REVERSAL_S, REVERSAL_SHARE)

__all__ = ["operating_conditions", "locate_mismatch", "velocity_estimate", "named_states", "episodes",
           "valve_null_and_span", "near_null", "moving_speed"]


def named_states(fit) -> dict:
    """A fit's model trajectory by state name: ``{state name: value at every sample (N,)}``."""
    X = fit.trajectory()
    return {name: X[:, i] for i, name in enumerate(fit.model.state_names)}


def velocity_estimate(time_s: np.ndarray, position_m: np.ndarray, window_s: float = 0.03) -> np.ndarray:
    """Piston velocity from the measured position by a Savitzky-Golay derivative, m/s (N,)."""
    from scipy.signal import savgol_filter

    dt = float(time_s[1] - time_s[0])
    w = max(5, int(round(window_s / dt)) | 1)
    n = position_m.size
    w = min(w, n if n % 2 else n - 1)
    if w < 5:
        return np.gradient(position_m, dt)
    return savgol_filter(position_m, w, 2, deriv=1, delta=dt)


def valve_null_and_span(rig) -> tuple[float, float]:
    """``(null, span)``: the rig's valve null and the span of its command range, V."""
    null = float(rig.params.get("valve_null_V", 5.0))
    span = float(rig.params.get("valve_max_V", 10.0) - rig.params.get("valve_min_V", 0.0))
    return null, span


def near_null(command_V: np.ndarray, rig, fraction: float = NEAR_NULL_SPAN) -> np.ndarray:
    """Where the valve command (N,) is within ``fraction`` of the valve's span of its null (N,) bool; the
    operating condition "valve near null" at the default :data:`~.rules.NEAR_NULL_SPAN`."""
    null, span = valve_null_and_span(rig)
    return np.abs(command_V - null) < fraction * span


def moving_speed(rig) -> float:
    """The speed above which the piston counts as moving, m/s (:data:`~.rules.MOVING_STROKE` of its stroke a
    second)."""
    return MOVING_STROKE * rig.stroke_m


def operating_conditions(recording, rig, velocity_m_per_s: np.ndarray | None = None) -> dict:
    """Boolean masks (N,) of the operating conditions named in ``diagnosis.md``.

    Thresholds are fractions of the rig's data sheet, each a rule of :mod:`.rules` ("the operating conditions"):
    the speed that counts as motion, how close to null the valve is "near null", how far from it a "large
    opening", how close to an end "near an end stop", a chamber pressure "high" (of supply) or "low" (in
    atmospheres), and how large and how recent a command change is a "fast command change".
    """
    t = recording.time_s
    x = recording.position_m
    u = recording.valve_cmd_V
    stroke = rig.stroke_m
    v = velocity_estimate(t, x) if velocity_m_per_s is None else velocity_m_per_s
    v_moving = moving_speed(rig)
    null, span = valve_null_and_span(rig)
    dt = float(t[1] - t[0])
    sign = np.sign(np.where(np.abs(v) > v_moving, v, 0.0))
    last = np.zeros_like(sign)
    current = 0.0
    for k, s in enumerate(sign):  # direction of the latest motion, for reversals
        if s != 0:
            current = s
        last[k] = current
    reversal = np.zeros(x.size, bool)
    flips = np.flatnonzero((np.diff(last) != 0) & (last[:-1] != 0)) + 1
    half = max(1, int(round(REVERSAL_S / dt)))
    for k in flips:
        reversal[max(0, k - half):k + half] = True
    du = np.abs(np.diff(u, prepend=u[0]))
    lookback = max(1, int(round(FAST_CHANGE_S / dt)))
    fast = np.convolve((du > FAST_CHANGE_SPAN * span).astype(float), np.ones(lookback), mode="full")[:x.size] > 0
    masks = {
        "extending": v > v_moving,
        "retracting": v < -v_moving,
        "holding still": np.abs(v) <= v_moving,
        "velocity reversal": reversal,
        "valve near null": near_null(u, rig),
        "large opening": np.abs(u - null) > LARGE_OPENING_HALF_SPAN * span / 2,
        "near an end stop": (x < END_STOP_STROKE * stroke) | (x > (1 - END_STOP_STROKE) * stroke),
        "right after a fast command change": fast,
    }
    if recording.has_pressures:
        supply = float(rig.params["supply_Pa"])
        atm = float(rig.params.get("atmosphere_Pa", 101325.0))
        pa, pb = recording.pressure_a_Pa, recording.pressure_b_Pa
        high, low = HIGH_PRESSURE_SUPPLY * supply, LOW_PRESSURE_ATMOSPHERES * atm
        masks["high chamber pressure"] = (pa > high) | (pb > high)
        masks["low chamber pressure"] = (pa < low) | (pb < low)
    return masks


def _describe(masks: dict, a: int, b: int) -> str:
    """The conditions that hold for most of samples ``a:b`` (or the most frequent ones)."""
    share = {name: float(np.mean(m[a:b])) for name, m in masks.items()}
    direction = max(("extending", "retracting", "holding still"), key=lambda k: share[k])
    words = []
    if share["velocity reversal"] > REVERSAL_SHARE:
        words.append("velocity reversal")
    words.append(direction)
    for name in ("valve near null", "large opening", "near an end stop", "high chamber pressure",
                 "low chamber pressure", "right after a fast command change"):
        if share.get(name, 0.0) > CONDITION_SHARE:
            words.append(name)
    return ", ".join(words)


def locate_mismatch(recording, rig, model_states: dict, noise_std: dict, window_s: float | None = None,
                    max_windows: int = MAX_WINDOWS) -> tuple[list[MismatchWindow], dict]:
    """Windows where the residual of a signal exceeds what its sensor noise explains.

    Parameters
    ----------
    recording : Recording
    rig : Rig
    model_states : dict
        ``{signal name: model value at every sample (N,)}`` (NaN where the model has none).
    noise_std : dict
        ``{signal name: sensor noise standard deviation}`` in the signal's unit.
    window_s : float, optional
        Length of the sliding window, s (default: :data:`~.rules.LOCATE_WINDOW_S`; at least
        :data:`~.rules.LOCATE_WINDOW_SAMPLES` samples).
    max_windows : int
        At most this many windows are returned, the strongest (by mean normalised square) first
        in time order.

    Returns
    -------
    windows : list of MismatchWindow
    info : dict
        ``threshold`` (of the windowed mean square of the normalised residual), ``window_samples``,
        and per signal the fraction of the recording flagged.
    """
    t = recording.time_s
    dt = float(t[1] - t[0])
    m = max(LOCATE_WINDOW_SAMPLES, int(round((window_s or LOCATE_WINDOW_S) / dt)))
    n = t.size
    n_windows = max(1, n // m)
    threshold = float(stats.chi2.ppf(1.0 - FALSE_ALARM / n_windows, m) / m)
    masks = operating_conditions(recording, rig)
    longest = max(m, int(EPISODE_LENGTH * n))
    found, info = [], {"threshold": threshold, "window_samples": m, "flagged_fraction": {}}
    measured = {"position_m": recording.position_m}
    if recording.has_pressures:
        measured["pressure_a_Pa"] = recording.pressure_a_Pa
        measured["pressure_b_Pa"] = recording.pressure_b_Pa
    for name, y in measured.items():
        yhat = model_states.get(name)
        sigma = float(noise_std.get(name, 0.0))
        if yhat is None or not sigma > 0:
            continue
        z2 = ((y - yhat) / sigma) ** 2
        z2 = np.where(np.isfinite(z2), z2, 0.0)
        mean_sq = np.convolve(z2, np.ones(m) / m, mode="same")
        flagged = mean_sq > threshold
        info["flagged_fraction"][name] = float(np.mean(flagged))
        edges = np.flatnonzero(np.diff(np.concatenate([[0], flagged.astype(int), [0]])))
        for a, b in _pieces(edges, longest):
            found.append(MismatchWindow(float(t[a]), float(t[min(b, n) - 1]), name, _describe(masks, a, b),
                                        float(np.max(mean_sq[a:b]))))
    found.sort(key=lambda w: -w.score)
    found = sorted(found[:max_windows], key=lambda w: (w.t_start_s, w.signal))
    return found, info


def _pieces(edges: np.ndarray, longest: int) -> list:
    """The flagged stretches (``edges``: alternate starts and stops) as windows of at most ``longest`` samples:
    a stretch longer than that is cut into equal pieces.

    Why: a model far from the recording is above noise nearly everywhere, and one window "0-20 s, holding still"
    tells a reader neither where the mismatch is largest nor under which condition; pieces of at most
    :data:`~.rules.EPISODE_LENGTH` of the recording each get their own condition and score, and the report shows the
    strongest."""
    out = []
    for a, b in zip(edges[::2], edges[1::2]):
        count = -(-(b - a) // longest)
        cuts = np.linspace(a, b, count + 1).round().astype(int)
        out += list(zip(cuts[:-1], cuts[1:]))
    return out


_SIGNAL_ORDER = ("position_m", "pressure_a_Pa", "pressure_b_Pa")


def episodes(windows: list, duration_s: float, max_episodes: int = MAX_EPISODES) -> list[MismatchWindow]:
    """Mismatch windows merged into a few episodes a reader can follow: windows closer than
    :data:`~.rules.EPISODE_GAP` of the recording's duration ``duration_s`` join one episode while it stays within
    :data:`~.rules.EPISODE_LENGTH` of it (a window that ends within the episode joins it whatever its length); an
    episode takes the signal, condition and score of its strongest window (its other signals in ``also_in``), and
    begins where the one before it ended at the earliest, so that no two overlap; the ``max_episodes`` strongest,
    in time order."""
    groups: list[list] = []
    gap, longest = EPISODE_GAP * duration_s, EPISODE_LENGTH * duration_s
    for w in sorted(windows, key=lambda w: w.t_start_s):
        if groups:
            end = max(x.t_end_s for x in groups[-1])
            if w.t_end_s <= end or (w.t_start_s - end <= gap and w.t_end_s - groups[-1][0].t_start_s <= longest):
                groups[-1].append(w)
                continue
        groups.append([w])
    merged, previous_end = [], -math.inf
    for group in groups:
        strongest = max(group, key=lambda w: w.score)
        others = sorted({w.signal for w in group} - {strongest.signal},
                        key=lambda s: _SIGNAL_ORDER.index(s) if s in _SIGNAL_ORDER else len(_SIGNAL_ORDER))
        end = max(w.t_end_s for w in group)
        merged.append(MismatchWindow(max(previous_end, min(w.t_start_s for w in group)), end,
                                     strongest.signal, strongest.condition, strongest.score, tuple(others)))
        previous_end = end
    merged.sort(key=lambda w: -w.score)
    return sorted(merged[:max(1, max_episodes)], key=lambda w: w.t_start_s)
