"""Several effects at once (``several_effects=True``, and the default search going on where it leaves the recording
unexplained), recovered from our own simulations: each found, its parameters within their
uncertainty of the truth, the report's plots drawn with their axes labelled.

The recordings are those of ``test_diagnosis`` (the paper-2 rig with every nominal free parameter off its data
sheet, 20 s of open-loop pulses with both pressures); the effects are switched on together.
"""

import math

import numpy as np
import pytest
from test_diagnosis import _simulate

from pneusim.diagnosis import diagnose, write_report
from pneusim.model import make_effect

#: the several-effects search as a user runs it, within its default time budget: counted in model work, the
#: budget buys the same search on every machine (decision record 0116); its own rules are tested in
#: ``test_several_effects_rules``
SEVERAL = {"several_effects": True}

#: the concealed effects and the parameter each is judged by, ``(effect, parameter, true value)``
TWO = (("valve_deadband", "deadband_V", 0.45), ("external_load", "force_N", -100.0))
THREE = TWO + (("friction_asymmetry", "retract_factor", 2.0),)


def _effects(truth):
    out = []
    for name, key, value in truth:
        options = {"kind": "constant"} if name == "external_load" else {}
        out.append(make_effect(name, **options, **{key: value}))
    return out


def _recovered(result, truth) -> None:
    """Every concealed effect found, nothing else named, each judged parameter within 3 standard errors (or
    2 % where the fit pins it tighter than the simulation's own discretisation) of the truth."""
    found = [f.effect for f in result.findings]
    assert sorted(found) == sorted(name for name, _, _ in truth), result.summary()
    by_name = {f.effect: f for f in result.findings}
    for name, key, value in truth:
        f = by_name[name]
        estimate, error = f.parameters[key], f.standard_errors.get(key)
        tolerance = max(3.0 * (error or 0.0), 0.02 * abs(value))
        assert math.isclose(estimate, value, abs_tol=tolerance), f"{name}.{key} = {estimate} +- {error}, truth {value}"
    assert result.status == "complete"
    assert result.final_fit_percent > 99.0


@pytest.fixture(scope="module")
def two_effects(tmp_path_factory):
    path = _simulate(tmp_path_factory.mktemp("two"), _effects(TWO))
    return diagnose(path, **SEVERAL)


@pytest.mark.minutes
def test_two_effects_at_once_are_both_found(two_effects):
    """A dead band and a constant load: the load explains most (a bias on every move), the dead band is
    found on top of it; drop-one keeps both."""
    _recovered(two_effects, TWO)
    assert two_effects.effects[0] == "external_load"
    # the nominal parameters had bent to make up for the missing physics, and move back with the findings
    assert set(two_effects.final_parameters) == set(two_effects.nominal["parameters"])


@pytest.mark.minutes
def test_the_report_draws_every_plot_with_its_axes_labelled(two_effects, tmp_path, monkeypatch):
    from pneusim.diagnosis import evidence, report

    drawn = {}
    save = report.savefig_atomic

    def recording_savefig(fig, path, **kwargs):
        drawn[path.name] = [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes]
        return save(fig, path, **kwargs)

    monkeypatch.setattr(report, "savefig_atomic", recording_savefig)
    monkeypatch.setattr(evidence, "savefig_atomic", recording_savefig)
    index = write_report(two_effects, tmp_path / "report")
    assert set(drawn) == {"fit.png", "zoom.png", "residuals.png", "evidence-1-external_load.png",
                          "evidence-2-valve_deadband.png"}
    for name, axes in drawn.items():
        assert (tmp_path / "report" / name).stat().st_size > 0
        assert all(y for _, y in axes), f"{name}: an axis without a y label"
        assert axes[-1][0] or name.startswith("evidence"), f"{name}: no x label on the bottom axis"
        assert all(x for x, _ in axes[:1]) or name in ("fit.png", "zoom.png", "residuals.png")
    zoom = [y for _, y in drawn["zoom.png"]]   # each signal above its residual, where a small mismatch shows
    assert len(zoom) % 2 == 0 and [y.startswith("measured - model") for y in zoom] == [False, True] * (len(zoom) // 2)
    text = (tmp_path / "report" / "report.md").read_text()
    assert "without the findings | with the findings" in text and "zoom.png" in text
    assert "Physics left out**, most important first: `external_load`, `valve_deadband`" in text
    assert index.read_text().count("<img") == 5
    # the fits fitted again with the rescue routes, if any ran, in the report as in the JSON
    rescues = two_effects.to_dict().get("rescues", [])
    assert ("## Fitted again with the rescue routes" in text) == bool(rescues)
    assert all(f"| {r['where']} | {', '.join(r['effects'])} |" in text for r in rescues)


@pytest.mark.minutes
def test_every_evidence_plot_an_effect_can_name_draws_with_its_axes_labelled(two_effects, tmp_path, monkeypatch):
    """Each kind of :data:`~pneusim.model.effects.EVIDENCE_PLOTS` is drawn (the evidence module has one function
    for each), with both axes labelled and both models' curves, on the two-effect diagnosis."""
    from pneusim.diagnosis import evidence
    from pneusim.model.effects import EVIDENCE_PLOTS

    drawn = {}
    save = evidence.savefig_atomic

    def recording_savefig(fig, path, **kwargs):
        ax = fig.axes[0]
        drawn[path.stem] = (ax.get_xlabel(), ax.get_ylabel(), [line.get_label() for line in ax.get_lines()])
        return save(fig, path, **kwargs)

    monkeypatch.setattr(evidence, "savefig_atomic", recording_savefig)
    for kind in EVIDENCE_PLOTS:
        evidence.plot_evidence(two_effects, 0, tmp_path / f"{kind}.png", kind=kind)
    assert set(drawn) == set(EVIDENCE_PLOTS)
    for kind, (xlabel, ylabel, labels) in drawn.items():
        assert xlabel and ylabel, kind
        assert {"nominal", "with findings"} <= set(labels), (kind, labels)


def test_the_holds_after_moves_count_from_each_stop_and_know_where_the_move_began():
    """The clock of the relaxation plot and of the settling signature: each run of held samples after motion
    starts at zero and knows where that motion began; a run the recording starts with follows no move and is
    left out."""
    from pneusim.diagnosis.signatures import hold_runs

    held = np.array([1, 1, 0, 0, 1, 1, 1, 0, 1], bool)
    since, stop, start = hold_runs(held, 0.5 * np.arange(held.size))
    assert np.array_equal(stop, [-1, -1, -1, -1, 4, 4, 4, -1, 8])
    assert np.array_equal(start, [-1, -1, -1, -1, 2, 2, 2, -1, 7])     # where the motion before each run began
    assert np.allclose(since[4:7], [0.0, 0.5, 1.0]) and since[8] == 0.0 and np.isnan(since[:4]).all()


def test_the_pressure_settling_signature_is_the_relaxation_not_the_sensor_noise():
    """Holds of 1 s after moves of 0.3 s, 300 Pa of white sensor noise on both chambers: where the model misses
    nothing, the settling signature stays within 0.15 kPa of zero (the noise averages out over the holds: 300 Pa
    over 46 holds and two chambers is a standard error of 0.03 kPa); where the measured pressures settle back by
    1 kPa (time constant 0.07 s) after each move and the model holds them, it reads 1 kPa."""
    from types import SimpleNamespace

    from pneusim.diagnosis.signatures import _hold_pressure_settling

    rng = np.random.default_rng(3)
    sample = np.arange(6000)                   # 10 ms samples, a move and its hold every 130 of them
    t, phase = 0.01 * sample, 0.01 * (sample % 130)
    moving = sample % 130 < 30
    direction = np.where((sample // 130) % 2 == 0, 1.0, -1.0)
    model = 4e5 + 2e4 * np.where(moving, direction * phase / 0.3, direction)
    since = np.where(moving, 0.0, phase - 0.3)
    relax = -1e3 * direction * (1.0 - np.exp(-since / 0.07))
    states = {"pressure_a_Pa": model, "pressure_b_Pa": 8e5 - model}
    for missing, expected in ((0.0, 0.0), (1.0, 1.0)):
        rec = SimpleNamespace(time_s=t, pressure_a_Pa=model + missing * relax + rng.normal(0, 300, t.size),
                              pressure_b_Pa=8e5 - model - missing * relax + rng.normal(0, 300, t.size))
        assert _hold_pressure_settling(rec, states, ~moving) == pytest.approx(expected, abs=0.15)


@pytest.mark.minutes
def test_three_effects_at_once_are_all_found_by_the_default_search(tmp_path):
    """A dead band, a constant load and seals that drag twice as hard retracting, diagnosed with the default
    options: the one-effect-first search models two effects at most, and where they leave the recording
    unexplained the several-effects search goes on from them; each found on top of the ones before it, all
    kept with the others present."""
    _recovered(diagnose(_simulate(tmp_path, _effects(THREE))), THREE)


@pytest.mark.minutes
def test_physics_outside_the_vocabulary_is_said_as_other_with_where_and_the_closest_candidates(shared_dir):
    """A recording of the independent practice simulator whose only missing physics is outside the
    vocabulary (one valve port's flow paths narrower than the other's), from the half of practice3 the method
    was developed on: the vocabulary effects that come closest (a leak lowers the estimation cost, seals that
    drag harder one way look asymmetric) fail the keep test, and the answer is ``other``, with the episodes
    where the residual is and the candidates with why each was rejected.  Two candidates only, to keep the test
    short (the whole vocabulary is the benchmark's, ``benchmarks/test_bench_diagnosis.py``)."""
    import json

    from pneusim.diagnosis.rules import MAX_EPISODES

    name = "practice3_27.csv"
    answer = json.loads((shared_dir / "practice3" / "answers.json").read_text())["cases"][name]
    assert [e["effect"] for e in answer["effects"]] == ["other"]
    result = diagnose(shared_dir / "practice3" / name, effects=["leakage", "friction_asymmetry"], **SEVERAL)
    assert result.effects == ["other"] and result.status == "complete"
    other = result.findings[0]
    # where: a few episodes inside the recording (here the residual is above noise nearly all along)
    assert 1 <= len(other.mismatch) <= MAX_EPISODES
    assert all(0.0 <= w.t_start_s <= w.t_end_s <= 80.0 and w.condition for w in other.mismatch)
    assert {c["effect"] for c in other.closest} == {"leakage", "friction_asymmetry"}
    # each says what rejected it: the keep test's failing part, or the fit's failure (under some arithmetic paths
    # the fit from the data sheet of one of them fails on this recording)
    assert all(c["why_rejected"] and c["effect"] not in result.effects for c in other.closest), other.closest
    assert "something not in the vocabulary" in other.evidence
    d = result.to_dict()["findings"][0]
    assert d["effect"] == "other" and d["mismatch"] and d["closest"]
