"""Effect ablations: the shipped files cover every effect at three magnitudes with a source, bad files are
refused naming the field, and a tiny ablation shows an effect costing the ARX model fit."""

import csv
import json

import pytest

from pneusim.errors import InputFileError
from pneusim.model import EFFECTS
from pneusim.scenario.ablation import LEVELS, PHYSICAL_EFFECT, PHYSICAL_NOMINAL
from pneusim.scenario.sweep import expand_runs, load_sweep, run_sweep

from ablation_cases import DEADBAND, write_tiny_ablation


@pytest.mark.parametrize("name, metric", [("ablation-paper1.toml", "square_error"),
                                          ("ablation-paper2.toml", "fit_percent")])
def test_shipped_ablations_cover_every_effect_at_three_levels(scenarios_dir, name, metric):
    sweep = load_sweep(scenarios_dir / name)
    ab = sweep["ablation"]
    assert ab["metric"] == metric
    rows = ab["rows"]
    cases = {(r["effect"], r["level"]) for r in rows if r["effect"]}
    assert cases == {(e, lv) for e in EFFECTS for lv in LEVELS}      # a newly registered effect must be added
    assert all(r["source"].strip() for r in rows)                      # every magnitude says where it comes from
    assert rows[0]["row"] == "ideal rig" and any(r["row"].startswith("realistic rig") for r in rows)
    assert sum(r["group"] == "combination" for r in rows) >= 2
    # physical fits only at the typical level (plus the references): the expensive part is restricted
    phys = [c for c in ab["labels"].values() if c["part"] == "physical"]
    assert {c["level"] for c in phys if c["effect"]} == {"typical"}
    names = [i["name"] for i in sweep["scenario"]["identifiers"]]
    assert PHYSICAL_NOMINAL in names and PHYSICAL_EFFECT in names
    assert len(expand_runs(sweep)) == len(ab["labels"])                # one run per case and part


@pytest.mark.parametrize("case, field", [
    (DEADBAND.replace('"valve_deadband"', '"valve_deadzone"'), "ablation.cases[0].effect"),
    (DEADBAND.replace('"high"', '"extreme"'), "ablation.cases[0].level"),
    (DEADBAND.replace("deadband_V", "band_V"), "ablation.cases[0].params"),
    (DEADBAND.replace('source = "10 % of the half span"', ""), "ablation.cases[0].source"),
])
def test_bad_ablation_cases_name_the_field(tmp_path, case, field):
    path = write_tiny_ablation(tmp_path, case)
    with pytest.raises(InputFileError) as err:
        load_sweep(path)
    assert str(path) in str(err.value) and field in str(err.value)


def test_tiny_ablation_dead_band_costs_the_arx_fit(tmp_path):
    path = write_tiny_ablation(tmp_path, DEADBAND)
    sweep = load_sweep(path)
    out = tmp_path / "out"
    info = run_sweep(sweep, out, workers=0, progress=False)
    assert info["n_failed"] == 0
    values = {(v["row"], v["identifier"]): v["value"]
              for v in json.loads((out / "ablation.json").read_text())["values"]}
    ideal, band = values[("ideal rig", "ARX")], values[("valve_deadband (high)", "ARX")]
    assert ideal > 90.0                       # sensor noise only: the closed loop is nearly linear
    assert ideal - band > 3.0                 # a 0.5 V dead band is a nonlinearity ARX cannot represent
    assert values[("paper", "ARX")] == pytest.approx(77.90)
    with open(out / "ablation.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert any(r["source"] == "10 % of the half span" and r["identifier"] == "ARX" for r in rows)
    assert "| valve_deadband (high) |" in (out / "ablation.md").read_text()
    assert (out / "ablation.png").stat().st_size > 1000
