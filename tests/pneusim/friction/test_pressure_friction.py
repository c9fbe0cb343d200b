"""The effect ``pressure_dependent_friction``: the same law as the practice2 generator, and a fit recovers it."""

import json

import numpy as np
import pytest

from pneusim.cli import main
from pneusim.experiment import standard_experiment
from pneusim.model import make_effect
from pneusim.model.effects import seal_pressure_factor
from pneusim.recording import write_recording
from pneusim.rig import load_rig
from pneusim.simulate import simulate


def test_law_matches_the_practice2_generator(shared_dir):
    """The generator states the range of |p_A - p_B| its runs reached and the friction over the plant's
    (reference) value it applied there; our factor at those differences must give the same numbers."""
    cases = json.loads((shared_dir / "practice2" / "answers.json").read_text())["cases"]
    checked = 0
    for name, case in cases.items():
        for effect in case["effects"]:
            if effect["effect"] != "pressure_dependent_friction":
                continue
            par = effect["parameters"]
            rig = load_rig(case["rig"])
            gauge = rig["supply_Pa"] - rig["atmosphere_Pa"]
            assert gauge == pytest.approx(par["supply_gauge_Pa"])
            d = np.array(case["diagnostics"]["pressure_difference_range_Pa"])
            expected = case["diagnostics"]["friction_over_plant_value_range"]
            k, d_ref = par["pressure_coefficient"], par["reference_difference_Pa"]
            # the law itself (|d| exact: d * sign(d)) ...
            exact = seal_pressure_factor(d, k, d_ref, gauge, tanh=np.sign)
            assert exact == pytest.approx(expected, rel=1e-9), name
            # ... and the model's smoothed |d| differs from it by at most 0.28 * 1 kPa of pressure difference
            smooth = seal_pressure_factor(d, k, d_ref, gauge, tanh=np.tanh)
            assert np.all(np.abs(smooth - exact) <= k * 0.28 * 1e3 / gauge / (1 + k * d_ref / gauge)), name
            # and the plant's levels are the levels at the reference difference
            at_reference = seal_pressure_factor(par["reference_difference_Pa"], par["pressure_coefficient"], 0.0,
                                                gauge, tanh=np.tanh)
            assert par["coulomb_at_zero_difference_N"] * at_reference == pytest.approx(
                case["plant"]["friction_coulomb_N"], rel=1e-9)
            checked += 1
    assert checked == 2


def test_fit_cli_recovers_a_known_pressure_coefficient(tmp_path, capsys):
    """``pneusim fit --effect pressure_dependent_friction --free ...pressure_coefficient`` on a 6 s closed-loop
    paper-2 recording with pressures (k = 3, fit started from the default k = 2)."""
    rig = load_rig("paper2-enfield")
    true_k = 3.0
    exp = standard_experiment(rig, "multisine", 6.0, "closed", seed=2)
    sim = simulate(rig, exp, [make_effect("pressure_dependent_friction", pressure_coefficient=true_k)], seed=3,
                   record_pressures=True)
    path, out = tmp_path / "run.csv", tmp_path / "fit.json"
    write_recording(sim.recording, path)
    name = "pressure_dependent_friction.pressure_coefficient"
    assert main(["fit", str(path), "--effect", "pressure_dependent_friction", "--free", name,
                 "--json", str(out), "--quiet"]) == 0
    p = json.loads(out.read_text())["parameters"][name]
    assert p["start"] == 2.0
    assert abs(p["estimate"] - true_k) <= 3.0 * p["std"], p
    assert abs(p["estimate"] / true_k - 1.0) < 0.05, p
    assert "validation fit" in capsys.readouterr().out
