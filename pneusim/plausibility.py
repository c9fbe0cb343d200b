"""Whether a recording is one its rig could have made: commands inside the valve's range, pressures
between atmosphere and supply, positions within the stroke; and the time spent at an end stop.

The recording format itself (:mod:`pneusim.recording`) knows no rig beyond its stroke; these checks
need the rig's data sheet and come before a fit or a check reports on the recording.
"""

from __future__ import annotations

import numpy as np

from .errors import InputFileError
from .recording import POSITION_MARGIN, PRESSURE_COLUMNS, Recording

__all__ = ["check_plausible", "end_stop_time", "end_stop_text", "COMMAND_MARGIN", "PRESSURE_LOW_MARGIN",
           "PRESSURE_HIGH_MARGIN", "END_STOP_BAND"]

#: a command may exceed the valve's range by this fraction of the range (rounding of a DAQ)
COMMAND_MARGIN = 0.01
#: pressures may lie this far below the lower of atmosphere and exhaust (a chamber drawn below
#: atmosphere by a fast stroke, sensor offset), as a fraction of it
PRESSURE_LOW_MARGIN = 0.2
#: pressures may lie this far above the supply, as a fraction of the supply gauge pressure
PRESSURE_HIGH_MARGIN = 0.1
#: a position within this fraction of the stroke from an end counts as "at the end stop"
END_STOP_BAND = 0.005


def check_plausible(recording: Recording, rig) -> None:
    """Refuse a recording that its rig cannot have made (one :class:`InputFileError` naming the sample).

    Checks: every valve command inside ``[valve_min_V, valve_max_V]`` (give or take
    :data:`COMMAND_MARGIN` of the range); every pressure (A, B, supply) between a little below
    atmosphere/exhaust and a little above the supply (:data:`PRESSURE_LOW_MARGIN`,
    :data:`PRESSURE_HIGH_MARGIN`: a pressure written in bar or kPa is refused); every position and
    reference within [-1 %, 101 %] of the rig's stroke.  Gaps (NaN) are skipped.
    """
    p = rig.params
    lo_v, hi_v = p["valve_min_V"], p["valve_max_V"]
    margin_v = COMMAND_MARGIN * (hi_v - lo_v)
    low_pa = (1.0 - PRESSURE_LOW_MARGIN) * min(p["atmosphere_Pa"], p["exhaust_Pa"])
    high_pa = p["supply_Pa"] + PRESSURE_HIGH_MARGIN * (p["supply_Pa"] - p["atmosphere_Pa"])
    stroke = rig.stroke_m
    limits = {"valve_cmd_V": (lo_v - margin_v, hi_v + margin_v, "V",
                              f"the valve's command range [{lo_v:g}, {hi_v:g}] V of rig {rig.name}"),
              "position_m": (-POSITION_MARGIN * stroke, (1 + POSITION_MARGIN) * stroke, "m",
                             f"[-1 %, 101 %] of the stroke {stroke:g} m of rig {rig.name}"),
              "reference_m": (-POSITION_MARGIN * stroke, (1 + POSITION_MARGIN) * stroke, "m",
                              f"[-1 %, 101 %] of the stroke {stroke:g} m of rig {rig.name}")}
    for name in PRESSURE_COLUMNS:
        limits[name] = (low_pa, high_pa, "Pa", f"[{low_pa:.6g}, {high_pa:.6g}] Pa absolute, from a little below "
                        f"atmosphere to a little above the supply {p['supply_Pa']:.6g} Pa of rig {rig.name}"
                        " (pressure written in bar or kPa, or gauge?)")
    for name, (lo, hi, unit, what) in limits.items():
        values = getattr(recording, name)
        if values is None:
            continue
        with np.errstate(invalid="ignore"):
            bad = np.flatnonzero((values < lo) | (values > hi))
        if bad.size:
            i = int(bad[0])
            line = None if recording.first_row_line is None else recording.first_row_line + i
            where = "" if line is not None else f"sample {i + 1}: "
            raise InputFileError(f"{where}{float(values[i])!r} {unit} at t = {recording.time_s[i]:.6g} s is outside {what}; "
                                 f"{bad.size} of {values.size} samples are", path=recording.source, line=line,
                                 field=name)


def end_stop_time(recording: Recording, stroke_m: float) -> dict[str, float]:
    """Time the recorded position spends at an end stop, in s: ``{"retracted_s", "extended_s", "total_s",
    "fraction"}``.  A sample is at a stop when its position is within :data:`END_STOP_BAND` of the
    stroke from that end (or beyond it)."""
    x = recording.position_m
    band = END_STOP_BAND * stroke_m
    ts = recording.sample_time_s
    retracted = float(np.count_nonzero(x <= band)) * ts
    extended = float(np.count_nonzero(x >= stroke_m - band)) * ts
    total = retracted + extended
    return {"retracted_s": retracted, "extended_s": extended, "total_s": total,
            "fraction": total / (recording.n_samples * ts)}


def end_stop_text(recording: Recording, stroke_m: float) -> str:
    """One line for people: the time at an end stop (and a warning word for an open-loop run that sits there)."""
    stops = end_stop_time(recording, stroke_m)
    text = (f"time at an end stop: {stops['total_s']:.6g} s ({100 * stops['fraction']:.3g} % of the run; "
            f"retracted {stops['retracted_s']:.6g} s, extended {stops['extended_s']:.6g} s)")
    if stops["fraction"] > 0.05 and recording.loop != "closed":
        text += " -- warning: the open-loop run drives the piston into a stop; the data there say little"
    return text
