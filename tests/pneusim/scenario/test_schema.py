"""Scenario files are validated with errors naming the file, the key and the expected value."""

import copy

import pytest

from pneusim.errors import InputFileError
from pneusim.scenario.schema import get_dotted, load_scenario, set_dotted, validate_scenario
from pneusim.scenario.sweep import load_sweep, parse_set_items


def _write(tmp_path, text):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_shipped_scenarios_validate(scenarios_dir):
    for name in ("paper1-online-rls", "paper2-multisine"):
        spec = load_scenario(scenarios_dir / f"{name}.toml")
        assert spec["scenario"]["name"] == name
        assert spec["identifiers"]


def test_paper2_multisine_is_as_printed(scenarios_dir):
    spec = load_scenario(scenarios_dir / "paper2-multisine.toml")
    comps = spec["experiment"]["signal"]["components"]
    assert comps == [[0.04, 0.6], [0.5, 0.08], [0.9, 0.6]]      # 0.6 Hz twice, as printed
    assert spec["experiment"]["duration_s"] / spec["experiment"]["sample_time_s"] == pytest.approx(8000)


@pytest.mark.parametrize("mutate, key, expected", [
    (lambda d: d["experiment"].update(loop="half"), "experiment.loop", "expected one of open, closed"),
    (lambda d: d["experiment"].update(duration_s="long"), "experiment.duration_s", "expected a number"),
    (lambda d: d["data"].update(estimation_fraction=1.5), "data.estimation_fraction", "(0, 1)"),
    (lambda d: d["identifiers"][0].update(kind="magic"), "identifiers[0].kind", "expected one of"),
    (lambda d: d["identifiers"][0].update(forgetting=1.2), "identifiers[0].forgetting", "(0, 1]"),
    (lambda d: d["experiment"].update(colour="red"), "experiment.colour", "unknown key"),
    (lambda d: d["experiment"]["signal"].pop("components"), "experiment.signal.components", "frequency_Hz"),
    (lambda d: d["rig"].pop("name"), "rig.name", "required key missing"),
])
def test_errors_name_file_key_and_expectation(scenarios_dir, mutate, key, expected):
    spec = load_scenario(scenarios_dir / "paper2-multisine.toml")
    spec["identifiers"].insert(0, {"name": "x", "kind": "rls", "order": 2})
    bad = copy.deepcopy(spec)
    mutate(bad)
    with pytest.raises(InputFileError) as err:
        validate_scenario(bad, where="my.toml")
    msg = str(err.value)
    assert "my.toml" in msg and f"'{key}'" in msg and expected in msg


def test_bad_toml_file_names_the_file(tmp_path):
    p = _write(tmp_path, "[scenario\nname=1")
    with pytest.raises(InputFileError, match="s.toml"):
        load_scenario(p)


def test_dotted_keys_and_set_items():
    d = {"rig": {"overrides": {}}, "identifiers": [{"order": 3}]}
    set_dotted(d, "rig.overrides.supply_Pa", 5e5)
    set_dotted(d, "identifiers.0.order", 4)
    assert get_dotted(d, "rig.overrides.supply_Pa") == 5e5 and d["identifiers"][0]["order"] == 4
    with pytest.raises(InputFileError, match="unknown scenario table"):
        set_dotted(d, "nothing.x", 1)
    assert parse_set_items(["a.b=3", "c=[1, 2]", "d=word"]) == {"a.b": 3, "c": [1, 2], "d": "word"}


def test_sweep_with_bad_key_is_refused(tmp_path, data_dir):
    p = tmp_path / "sw.toml"
    p.write_text(f'[sweep]\nscenario = "{data_dir / "tiny-open-loop.toml"}"\n[grid]\n"experiment.colour" = [1, 2]\n')
    with pytest.raises(InputFileError, match="experiment.colour"):
        load_sweep(p)


@pytest.mark.parametrize("mutate, key, words", [
    (lambda d: d["experiment"].update(noise_scale=1e300), "experiment.noise_scale", "at most"),
    (lambda d: d["identifiers"][1].update(forgetting=1e-300), "identifiers[1].forgetting", "forgetting must be in"),
    (lambda d: d["identifiers"][1].update(initial_covariance=1e308), "identifiers[1].initial_covariance",
     "too large"),
    (lambda d: d["identifiers"][1].update(horizons=[1, 100000]), "identifiers[1].horizons", "shorter than the run"),
])
def test_settings_that_cannot_give_a_result_are_refused(mutate, key, words):
    """What the mixed-reality loop refuses, a scenario refuses too: a noise no recording can hold, an online
    estimator that cannot give an estimate, a prediction horizon beyond the run."""
    from pathlib import Path

    spec = load_scenario(Path(__file__).with_name("data") / "tiny-open-loop.toml")
    assert spec["identifiers"][1]["kind"] == "rls"
    data = copy.deepcopy(spec)
    mutate(data)
    with pytest.raises(InputFileError) as err:
        validate_scenario(data, where="s.toml")
    assert err.value.field == key and words in str(err.value)
