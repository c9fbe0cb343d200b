"""Whether a recording is one its rig could have made: the rig that made it, commands inside the valve's
range, pressures between atmosphere and supply, positions within the stroke, a sample time the rig
samples at; and the time spent at an end stop.

The recording format itself (:mod:`pneusim.recording`) knows no rig beyond its stroke; these checks
need the rig's data sheet and come before a fit, a diagnosis or a check reports on the recording.
:func:`recording_rig` finds that data sheet: the rig given, else the rig file the recording was made
with (which must still exist, unchanged), else the shipped rig it names.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import InputFileError, PneusimError
from .recording import POSITION_MARGIN, PRESSURE_COLUMNS, Recording
from .rig import Rig, known_rig_names, load_rig

__all__ = ["check_plausible", "check_sample_time", "recording_rig", "rig_file_sha256", "noise_scale_limit",
           "check_noise_scale", "end_stop_time", "end_stop_text", "COMMAND_MARGIN", "PRESSURE_LOW_MARGIN",
           "PRESSURE_HIGH_MARGIN", "END_STOP_BAND", "SAMPLE_TIME_RTOL", "NOISE_SIGMAS"]

#: a command may exceed the valve's range by this fraction of the range (rounding of a DAQ)
COMMAND_MARGIN = 0.01
#: pressures may lie this far below the lower of atmosphere and exhaust (a chamber drawn below
#: atmosphere by a fast stroke, sensor offset), as a fraction of it
PRESSURE_LOW_MARGIN = 0.2
#: pressures may lie this far above the supply, as a fraction of the supply gauge pressure
PRESSURE_HIGH_MARGIN = 0.1
#: a position within this fraction of the stroke from an end counts as "at the end stop"
END_STOP_BAND = 0.005
#: sample times closer than this (relative) are the same sample time (a decimal written in a file)
SAMPLE_TIME_RTOL = 1e-9
#: a scaled sensor noise must keep this many standard deviations between a reading and the end of what the
#: format can hold (an absolute pressure of 0; the stroke's margin for a position no converter clips)
NOISE_SIGMAS = 5.0


def noise_scale_limit(rig) -> float:
    """The largest noise scale whose sensor noise leaves readings the recording format can hold.

    A chamber at atmosphere (or exhaust) read with noise of ``scale * pressure_noise_std_Pa`` falls below
    vacuum, and the recording is refused, once :data:`NOISE_SIGMAS` standard deviations reach the lower of
    the two pressures; a position no converter clips (``position_adc_bits = 0``) leaves the stroke's
    margin the same way.  ``inf`` for ideal sensors.
    """
    p = rig.params
    limits = [math.inf]
    if p["pressure_noise_std_Pa"] > 0:
        limits.append(min(p["atmosphere_Pa"], p["exhaust_Pa"]) / (NOISE_SIGMAS * p["pressure_noise_std_Pa"]))
    if p["position_noise_std_m"] > 0 and int(p["position_adc_bits"]) <= 0:
        limits.append(POSITION_MARGIN * rig.stroke_m / (NOISE_SIGMAS * p["position_noise_std_m"]))
    return min(limits)


def check_noise_scale(rig, noise_scale: float, what: str) -> None:
    """Refuse a noise scale above :func:`noise_scale_limit` in one sentence naming ``what`` (the option or
    the file and key that set it)."""
    limit = noise_scale_limit(rig)
    if not noise_scale <= limit:
        raise PneusimError(f"{what} = {noise_scale:g}: expected at most {limit:.4g} for rig {rig.name}; beyond it "
                           f"the sensor noise ({rig.params['pressure_noise_std_Pa']:g} Pa times the scale) puts "
                           f"readings {NOISE_SIGMAS:g} standard deviations past what a recording can hold (an "
                           "absolute pressure of 0), and the recording would be refused")


def rig_file_sha256(path) -> str:
    """SHA-256 (hex) of a rig file's bytes: a recording keeps it (``rig_file_sha256``) beside ``rig_file``,
    so that a rig file changed since the recording was made is not taken for the one that made it."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def recording_rig(recording: Recording, rig=None, *, where: str | None = None,
                  load: Callable[[str], Rig] = load_rig) -> Rig:
    """The rig a recording is checked, fitted, diagnosed or re-run against (its data sheet; the
    recording's ``rig_overrides`` are not applied).

    ``rig`` (a :class:`~pneusim.rig.Rig`, a shipped name or a rig file) wins.  Else the rig file of the
    recording's ``rig_file`` metadata, which must still exist and, where the recording keeps its
    ``rig_file_sha256``, be unchanged: a recording made on a rig file is never silently re-run on the
    shipped rig of the same name.  Else its ``rig`` name, which must be a shipped rig.  ``load`` loads a
    name or a file (the commands pass one that also checks the rig file's other sections).

    Raises
    ------
    PneusimError
        One sentence naming the recording, the metadata key and what to give instead.
    """
    where = where or str(recording.source or "the recording")
    if isinstance(rig, Rig):
        return rig
    if rig:
        return load(str(rig))
    meta = recording.metadata
    name = recording.rig
    rig_file = meta.get("rig_file")
    if rig_file:
        if not Path(rig_file).is_file():
            shipped = f"; it is not the shipped rig {name}" if name in known_rig_names() else ""
            raise PneusimError(f"{where}: metadata 'rig_file: {rig_file}': the rig file the recording was made "
                               f"with no longer exists{shipped}; give --rig FILE.toml, that rig file")
        kept = meta.get("rig_file_sha256")
        if kept and kept != rig_file_sha256(rig_file):
            raise PneusimError(f"{where}: metadata 'rig_file: {rig_file}': the rig file has changed since the "
                               "recording was made (rig_file_sha256 differs); give --rig "
                               f"{rig_file} to use it as it is now, or the rig file as it was")
        return load(rig_file)
    if not name:
        raise PneusimError(f"{where} names no rig in its metadata ('# rig: ...'); give --rig NAME or --rig FILE.toml")
    try:
        return load(name)
    except PneusimError as exc:
        if "unknown rig" not in str(exc):
            raise   # a rig file that exists but is broken: its own message names the field
        raise PneusimError(f"{where}: metadata 'rig: {name}' is not a known rig (shipped: "
                           f"{', '.join(known_rig_names())}); give --rig FILE.toml, the rig file of "
                           "the rig that recorded it") from None


def check_sample_time(recording: Recording, rig) -> None:
    """Refuse a recording of another rig at another sample time: the recording names a rig other than
    ``rig`` *and* was sampled at another rate than ``rig`` samples at.

    Either alone is allowed (a user's copy of a data sheet under another name; the rig that made it, run
    at another sample time); both together say the recording is checked against the wrong rig, and a
    fit or a diagnosis against that data sheet would bend the model to it and name effects that are
    not there.
    """
    ts, rig_ts = recording.sample_time_s, rig.sample_time_s
    named = recording.rig
    if math.isclose(ts, rig_ts, rel_tol=SAMPLE_TIME_RTOL) or not named or named == rig.name:
        return
    raise InputFileError(f"recorded every {ts:g} s by rig {named!r}, while rig {rig.name} samples every {rig_ts:g} s: "
                         f"this is not a recording of {rig.name}; give --rig {named} (or the rig file of the rig "
                         "that recorded it)", path=recording.source, field="sample_time_s")


def check_plausible(recording: Recording, rig) -> None:
    """Refuse a recording that its rig cannot have made (one :class:`InputFileError` naming the sample).

    Checks: every valve command inside ``[valve_min_V, valve_max_V]`` (give or take
    :data:`COMMAND_MARGIN` of the range); every pressure (A, B, supply) between a little below
    atmosphere/exhaust and a little above the supply (:data:`PRESSURE_LOW_MARGIN`,
    :data:`PRESSURE_HIGH_MARGIN`: a pressure written in bar or kPa is refused); every position and
    reference within [-1 %, 101 %] of the rig's stroke (gaps, NaN, are skipped); then the sample time
    (:func:`check_sample_time`).
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
    check_sample_time(recording, rig)


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
