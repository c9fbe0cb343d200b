"""Every registered effect declares all of its facts, and what the fit and the diagnosis build from the
registry is what they used before effects became one module each.

The pins (``data/effect_registry_pins.json``) were captured from the code before the move, for both
shipped rigs at sample times of 1 and 10 ms: the screening candidates (label, effect values and
options, freed parameters, start scales, information-criterion count, trust-region evaluations), the
starts the screening from the data sheet keeps, and the fit's scale and bounds of every freed effect
parameter at a few starting values.  A change to any of them is a change of the diagnosis's or the
fit's behaviour, and must be made on purpose (and the pins regenerated with it).
"""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from pneusim.model import ActuatorModel, RIG_PARAMETERS
from pneusim.model.effects import (EFFECTS, EVIDENCE_PLOTS, LOOK_ALIKE_FAMILIES, Effect, ScreeningStart, in_range,
                                   missing_facts)
from pneusim.rig import load_rig

PINS = json.loads((Path(__file__).parent / "data" / "effect_registry_pins.json").read_text())
RIGS = ("paper1-mre", "paper2-enfield")
SAMPLE_TIMES_S = (0.001, 0.01)

#: unit words of parameter names (SI, ``_per_`` for a quotient, ``m3`` for a power)
_UNIT = r"(V|Hz|s|K|N|m|m2|m3|Pa|kg|W|J)"
_UNIT_SUFFIX = re.compile(rf"_{_UNIT}(_{_UNIT})*(_per_{_UNIT}(_{_UNIT})*)?$")
#: the last word of a dimensionless quantity's name
_DIMENSIONLESS = ("damping", "factor", "coefficient", "ratio")

#: every signature number of :func:`pneusim.diagnosis.signatures.compute_signatures`
SIGNATURES = dict(direction_r=0.41, extend_mean_mm_s=-1.5, retract_mean_mm_s=2.25, position_r=-0.33,
                  pressure_r=0.71, long_move_r=0.2, lag_s=0.012, lag_r=0.5, flat_spot_V=0.042,
                  small_command_speed_deficit=0.37, null_shift_V=-0.12, creep_mm_s=0.75,
                  hold_pressure_settling_kPa=1.23)

effects = pytest.mark.parametrize("cls", list(EFFECTS.values()), ids=list(EFFECTS))


@pytest.fixture(scope="module")
def rigs():
    return {name: load_rig(name) for name in RIGS}


@effects
def test_every_fact_is_declared(cls):
    assert missing_facts(cls) == []
    assert cls.name and cls.description.strip() and cls.source.strip()
    assert (cls.__dict__.get("__doc__") or "").strip(), "the class docstring gives the law"


@effects
def test_parameters_have_units_and_defaults_in_range(cls):
    assert cls.parameters
    for key, default in cls.parameters.items():
        assert _UNIT_SUFFIX.search(key) or key.split("_")[-1] in _DIMENSIONLESS, f"{cls.name}.{key}: no unit"
        assert in_range(default, cls.ranges.get(key)), (key, default)
    assert set(cls.ranges) <= set(cls.parameters)
    for key, choices in cls.options.items():
        assert choices and all(isinstance(c, str) for c in choices), key


@effects
def test_what_the_fit_frees_is_the_effects_own_and_has_a_scale_and_bounds(cls):
    from pneusim.fit.parameters import parameter_bounds, parameter_scale

    assert cls.fit_free, "an effect frees at least one parameter (or searches it)"
    assert set(cls.fit_free) <= set(cls.parameters)
    assert set(cls.searched) <= set(cls.fit_free)
    assert set(cls.fit_scale) <= set(cls.parameters)
    for key in cls.fit_free:
        assert key in cls.fit_scale, f"{cls.name}.{key} has no scale and bounds"
        assert len(cls.fit_scale[key]) == 3
        q, default = f"{cls.name}.{key}", cls.parameters[key]
        assert parameter_scale(q, default) > 0
        lo, hi = parameter_bounds(q, default)
        assert lo < hi and lo <= default <= hi, (q, lo, hi)


@effects
def test_the_diagnosis_facts_are_well_formed(cls, rigs):
    assert cls.family in LOOK_ALIKE_FAMILIES
    assert cls.evidence_plot in EVIDENCE_PLOTS
    for key, floor in cls.refit_start_floor.items():   # a start a refit can take: inside the range, a free parameter
        assert key in cls.fit_free and in_range(floor, cls.ranges.get(key)), (key, floor)
    assert isinstance(cls.scanned, bool)
    if cls.neutral is not None:
        assert cls.neutral and set(cls.neutral) <= set(cls.parameters)
        cls(**cls.neutral)   # a valid effect
    defaults = cls()
    assert set(cls.reported_options(defaults.option_values)) <= set(cls.options)
    derived = cls.derived_parameters(dict(defaults.values), lambda key: float(rigs[RIGS[0]].params[key]))
    assert derived.items() >= defaults.values.items()
    assert cls.added_parameters([f"{cls.name}.{k}" for k in cls.fit_free if k not in cls.searched]) >= 1
    state = defaults.initial_state(ActuatorModel([defaults]).param_dict(rigs[RIGS[0]]), 0.0)
    assert set(state) == set(cls.states)
    assert math.isfinite(defaults.static_force_N(ActuatorModel([defaults]).param_dict(rigs[RIGS[0]]), 0.05))


@effects
def test_screening_starts_build_valid_effects(cls, rigs):
    for rig_name, rig in rigs.items():
        for dt in SAMPLE_TIMES_S:
            starts = cls.screening_starts(rig.params, dt)
            assert starts, f"{cls.name} has no screening start for {rig_name} at {dt} s"
            labels = [s.label for s in starts]
            assert len(set(labels)) == len(labels) and all(labels)
            for start in starts:
                assert isinstance(start, ScreeningStart) and type(start.effect) is cls
                assert set(start.start_scale) <= set(RIG_PARAMETERS)
                assert all(v > 0 and math.isfinite(v) for v in start.start_scale.values())
            if cls.data_sheet_start is not None:
                key, value = cls.data_sheet_start
                kept = [s for s in starts if math.isclose(s.effect.values[key], value, rel_tol=1e-9, abs_tol=1e-12)]
                assert len(kept) == 1, (cls.name, rig_name, dt, labels)
    rig = rigs[RIGS[1]]
    for start in cls.screening_starts(rig.params, SAMPLE_TIMES_S[0]):   # each switched on in the model
        model = ActuatorModel([start.effect])
        x = model.initial_state(rig, 0.5 * rig.stroke_m, command_V=5.5)
        assert np.all(np.isfinite(np.asarray(model.rhs(x, 5.5, model.param_vector(rig))).ravel())), start.label


@effects
def test_evidence_is_said_in_words(cls):
    text = cls.evidence(SIGNATURES)
    assert text and any(ch.isdigit() for ch in text)
    unknown = cls.evidence({k: float("nan") for k in SIGNATURES})
    assert "n/a" in unknown


def test_an_effect_missing_facts_is_caught():
    class Backlash(Effect):
        name = "backlash"
        description = "play between rod and load"
        parameters = {"gap_m": 1e-3}

    assert missing_facts(Backlash) == ["source", "fit_free", "family", "neutral", "data_sheet_start",
                                       "screening_starts", "evidence"]


# --------------------------------------------------------------------- the registry's views, pinned
def registry_views(rigs) -> dict:
    """What the fit and the diagnosis build from the registry, in the form of the pins."""
    from pneusim.diagnosis import candidates as cand
    from pneusim.diagnosis.from_data_sheet import one_start_each
    from pneusim.diagnosis.candidates import FAMILIES
    from pneusim.fit import EFFECT_FREE
    from pneusim.fit.parameters import SEARCHED, parameter_bounds, parameter_scale

    views = {"effects": list(EFFECTS), "effect_free": {k: list(v) for k, v in EFFECT_FREE.items()},
             "searched": list(SEARCHED), "families": sorted(sorted(f) for f in FAMILIES),
             "neutral": cand.NEUTRAL, "candidates": {}, "data_sheet_starts": {}, "scale_bounds": {}}
    for rig_name, rig in rigs.items():
        for dt in SAMPLE_TIMES_S:
            candidates = cand.candidate_list(rig, dt)
            views["candidates"][f"{rig_name} {dt}"] = [
                {"name": c.name, "label": c.label, "values": c.effect.values, "options": c.effect.option_values,
                 "free": c.free, "start_scale": c.start_scale, "n_added": c.n_added,
                 "evaluations": cand.screen_evaluations(c)} for c in candidates]
            views["data_sheet_starts"][f"{rig_name} {dt}"] = [c.label for c in one_start_each(candidates)]
    for q in sorted({q for v in EFFECT_FREE.values() for q in v} | {"heat_transfer.wall_temperature_K"}):
        effect, _, key = q.partition(".")
        for start in sorted({0.0, EFFECTS[effect].parameters[key], 1e-11, 0.5, -3.0, 120.0}):
            views["scale_bounds"][f"{q} {start!r}"] = [parameter_scale(q, start), list(parameter_bounds(q, start))]
    return views


@pytest.fixture(scope="module")
def views(rigs):
    return registry_views(rigs)


def test_the_registry_order_and_the_fit_tables_are_as_pinned(views):
    assert views["effects"] == PINS["effects"]
    assert views["effect_free"] == PINS["effect_free"]
    assert views["searched"] == PINS["searched"]
    assert len(PINS["scale_bounds"]) > 50
    assert views["scale_bounds"].keys() == PINS["scale_bounds"].keys()
    for key, pinned in PINS["scale_bounds"].items():
        assert views["scale_bounds"][key] == pinned, key   # == to the last bit, not approx


def test_the_diagnosis_views_are_as_pinned(views):
    from pneusim.diagnosis.candidates import FAMILIES, family_of as _family

    assert views["neutral"] == PINS["neutral"]
    assert views["families"] == PINS["families"]
    for family in FAMILIES:
        for name in family:
            assert _family(name) == family
    assert _family("other") == ("other",)
    assert views["candidates"].keys() == PINS["candidates"].keys()
    for key, pinned in PINS["candidates"].items():
        assert [c["label"] for c in views["candidates"][key]] == [c["label"] for c in pinned], key
        assert views["candidates"][key] == pinned, key
        assert views["data_sheet_starts"][key] == PINS["data_sheet_starts"][key], key


if __name__ == "__main__":   # regenerate the pins on purpose: python tests/pneusim/model/test_effect_contract.py
    out = Path(__file__).parent / "data" / "effect_registry_pins.json"
    out.write_text(json.dumps(registry_views({name: load_rig(name) for name in RIGS}), indent=1) + "\n")
    print(f"wrote {out}")
