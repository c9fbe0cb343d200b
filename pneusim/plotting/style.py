"""The figure standard's vocabulary: one colour per role and model family, engineering units, labels.

Every report draws the same thing the same way: the measured signal black, the reference grey and dashed,
the nominal physical model orange, the fitted physical model blue, and each black-box family its own
colour (ARX vermilion, ARMAX pink, OE green, BJ brown, state space purple, transfer function cyan, the
papers' published models olive, recursive least squares a green ramp by order), from the Okabe-Ito and
Tableau palettes so that the families stay apart for colour-blind readers.  Quantities are shown in the
units a reader of a rig uses: position in mm, velocity in mm/s, pressure in bar gauge (or bar absolute
where the absolute value matters), time in s, latency in ms.
"""

from __future__ import annotations

import re

import numpy as np

__all__ = ["COLOURS", "RLS_ORDER_COLOURS", "STANDARD_ATMOSPHERE_PA", "family_of", "colour_for", "model_styles",
           "fit_label", "mm", "mm_per_s", "bar_gauge", "bar_abs", "ms", "parameter_axis"]

#: one colour per role or model family, the same in every report and notebook
COLOURS = {
    "measured": "#000000",
    "reference": "#7f7f7f",
    "command": "#6a3d9a",
    "nominal": "#E69F00",
    "physical": "#0072B2",
    "improved": "#56B4E9",
    "arx": "#D55E00",
    "armax": "#CC79A7",
    "oe": "#009E73",
    "bj": "#8C564B",
    "ss": "#9467BD",
    "tf": "#17BECF",
    "published": "#999933",
    "rls": "#2CA02C",
    "chamber_a": "#B2182B",
    "chamber_b": "#2166AC",
    "noise": "#D9D9D9",
    "window": "#FDD49E",
}
#: recursive least squares by model order: lighter to darker green
RLS_ORDER_COLOURS = {1: "#C7E9C0", 2: "#A1D99B", 3: "#74C476", 4: "#238B45", 5: "#00441B", 6: "#002A10"}

#: the atmosphere a gauge pressure is read against when the rig gives none, Pa (ISO 2533 sea level)
STANDARD_ATMOSPHERE_PA = 101325.0

_KIND_FAMILY = {"arx": "arx", "armax": "armax", "oe": "oe", "bj": "bj", "ss": "ss", "n4sid": "ss", "tf": "tf",
                "tfest": "tf", "rls": "rls", "recursive_arx": "rls", "published_z": "published",
                "published_s": "published", "physical_fit": "physical"}
# the first pattern that matches a label names its family (ARMAX before ARX: "armax" contains "arx")
_NAME_FAMILY = (
    (r"\barmax\b", "armax"), (r"\barx\b", "arx"), (r"\boe\b|output.error", "oe"), (r"\bbj\b|box.jenkins", "bj"),
    (r"state.space|n4sid|\bss\b", "ss"), (r"transfer.function|\btf\b|tfest", "tf"),
    (r"\brls\b|recursive|forgetting|lambda|\border \d", "rls"), (r"published|\beq\. ?\d", "published"),
    (r"nominal", "nominal"), (r"improved|with the effect|\+ ", "improved"), (r"physical|fitted|told", "physical"),
    (r"measured|actual|recorded", "measured"), (r"reference|set.?point", "reference"),
)


def family_of(name: str, kind: str | None = None) -> str | None:
    """The colour family of a model or signal: from its identifier ``kind`` when given, else from its name
    (``"ARX [3 3 1]"`` -> ``"arx"``, ``"physical, told 2 bar"`` -> ``"physical"``); None when none fits."""
    if kind in _KIND_FAMILY:
        return _KIND_FAMILY[kind]
    text = name.lower()
    for pattern, family in _NAME_FAMILY:
        if re.search(pattern, text):
            return family
    return None


def colour_for(name: str, kind: str | None = None, order: int | None = None) -> str | None:
    """The standard colour of a model or signal (see :data:`COLOURS`); recursive least squares by its
    ``order`` (given, or read from ``"order N"`` in the name).  None for a name of no known family."""
    family = family_of(name, kind)
    if family == "rls":
        if order is None:
            m = re.search(r"order (\d+)", name.lower())
            order = int(m.group(1)) if m else None
        return RLS_ORDER_COLOURS.get(order, COLOURS["rls"])
    return COLOURS.get(family)


_DASHES = ("-", "--", "-.", ":")
_MARKERS = ("o", "s", "^", "D")
_SPARE = ("#E377C2", "#BCBD22", "#1F77B4", "#FF7F0E", "#7F7F7F", "#AEC7E8")


def model_styles(names, kinds=None) -> dict[str, dict]:
    """``{name: {"color", "ls", "marker"}}`` for several models in one figure: each its family's colour; a
    second model of the same family a darker shade, dashed, with square markers, a third a lighter shade,
    dash-dotted, with triangles; a name of no known family a spare colour."""
    names = list(names)
    kinds = list(kinds) if kinds is not None else [None] * len(names)
    styles, used, spare = {}, {}, iter(_SPARE * 4)
    for name, kind in zip(names, kinds):
        colour = colour_for(name, kind) or next(spare)
        n = used.get(colour, 0)
        used[colour] = n + 1
        styles[name] = {"color": _shade(colour, _SHADES[n % len(_SHADES)]), "ls": _DASHES[n % len(_DASHES)],
                        "marker": _MARKERS[n % len(_MARKERS)]}
    return styles


# the n-th model of one family: its colour mixed with black (negative) or white (positive) by this share
_SHADES = (0.0, -0.4, 0.45, -0.65)


def _shade(colour: str, share: float) -> str:
    """``colour`` (``#RRGGBB``) mixed with black (``share`` < 0) or white (``share`` > 0)."""
    if share == 0.0 or not colour.startswith("#"):
        return colour
    rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)], dtype=float)
    target = 255.0 if share > 0 else 0.0
    mixed = rgb + abs(share) * (target - rgb)
    return "#" + "".join(f"{int(round(v)):02X}" for v in mixed)


def fit_label(name: str, fit_percent, digits: int = 1) -> str:
    """A legend entry with the model's fit: ``"ARX [3 3 1]: 95.8 %"`` (the name alone when the fit is
    missing or not finite)."""
    if fit_percent is None or not np.isfinite(fit_percent):
        return name
    return f"{name}: {fit_percent:.{digits}f} %"


def mm(x_m):
    """Metres to millimetres."""
    return np.asarray(x_m, dtype=float) * 1e3


def mm_per_s(v_m_per_s):
    """Metres per second to millimetres per second."""
    return np.asarray(v_m_per_s, dtype=float) * 1e3


def bar_gauge(p_Pa, atmosphere_Pa: float = STANDARD_ATMOSPHERE_PA):
    """Absolute pressure in Pa to bar above the atmosphere."""
    return (np.asarray(p_Pa, dtype=float) - atmosphere_Pa) / 1e5


def bar_abs(p_Pa):
    """Absolute pressure in Pa to bar absolute."""
    return np.asarray(p_Pa, dtype=float) / 1e5


def ms(t_s):
    """Seconds to milliseconds."""
    return np.asarray(t_s, dtype=float) * 1e3


# a varied key's last part -> (axis label, conversion from the SI value); checked in this order
_KNOWN_KEYS = (
    (r"supply_Pa$", "supply pressure (bar gauge)", bar_gauge),
    (r"moving_mass_kg$", "moving mass (kg)", None),
    (r"noise_scale$", "sensor noise (x the rig's noise std)", None),
    (r"sample_time_s$", "sample time (ms)", ms),
    (r"delay_s$", "delay (ms)", ms),
    (r"forgetting$", "forgetting factor lambda (-)", None),
    (r"duration_s$", "record length (s)", None),
    (r"_Pa$", "{} (bar abs)", bar_abs),
    (r"_m_per_s$", "{} (mm/s)", mm_per_s),
    (r"_m$", "{} (mm)", mm),
    (r"_s$", "{} (s)", None),
    (r"_kg$", "{} (kg)", None),
    (r"_N$", "{} (N)", None),
    (r"_V$", "{} (V)", None),
    (r"_Hz$", "{} (Hz)", None),
)


def parameter_axis(key: str):
    """``(axis label, conversion)`` for a varied key such as ``"rig.overrides.supply_Pa"``: the quantity in
    words with its engineering unit (supply pressure in bar gauge, lengths in mm ...) and a function from
    the key's SI value to that unit (None: shown as it is)."""
    last = key.split(".")[-1]
    for pattern, label, convert in _KNOWN_KEYS:
        if re.search(pattern, last):
            words = re.sub(pattern, "", last).replace("_", " ").strip() or last
            return label.format(words), convert
    return f"{last.replace('_', ' ')} (-)", None
