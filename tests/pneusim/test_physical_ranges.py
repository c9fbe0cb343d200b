"""Every numeric input gets its physical range checked where it enters.

Rig files and ``--param`` overrides, effect parameters, scenario values, and recordings that
their rig cannot have made: each refused in one line naming the parameter (or column) and the
range, before any simulation or fit runs.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import pneusim.commands.fit as fit_command
from pneusim.cli import build_parser, main, run_command
from pneusim.errors import InputFileError, PneusimError
from pneusim.model import make_effect
from pneusim.plausibility import check_plausible, end_stop_time
from pneusim.recording import Recording, read_recording, write_recording
from pneusim.rig import load_rig, write_rig


def _rig_file(tmp_path, old, new, name="bad.toml"):
    source = open(load_rig("paper1-mre").source).read()
    assert old in source
    path = tmp_path / name
    path.write_text(source.replace(old, new))
    return path


@pytest.mark.parametrize("old, new, field, words", [
    ("supply_Pa = 701325.0", "supply_Pa = 201325.0", "supply_Pa", "above exhaust_Pa"),
    ("moving_mass_kg = 0.35", "moving_mass_kg = 0.35\nmoving_mas_kg = 0.5", "typical.moving_mas_kg",
     "did you mean 'moving_mass_kg'"),
    ("position_adc_bits = 16", "position_adc_bits = 16.5", "position_adc_bits", "whole number"),
    ("friction_coulomb_N = 10.0", "friction_coulomb_N = nan", "friction_coulomb_N", ">= 0 N"),
    ("friction_static_N = 15.0", "friction_static_N = inf", "friction_static_N", ">= 0 N"),
    ("friction_viscous_N_s_per_m = 30.0", "friction_viscous_N_s_per_m = -1.0", "friction_viscous_N_s_per_m", ">= 0"),
    ("endstop_damping_N_s_per_m = 2000.0", "endstop_damping_N_s_per_m = -5.0", "endstop_damping_N_s_per_m", ">= 0"),
    ("pressure_noise_std_Pa = 300.0", "pressure_noise_std_Pa = -300.0", "pressure_noise_std_Pa", ">= 0"),
    ("valve_null_V = 5.0", "valve_null_V = 12.0", "valve_null_V", "between valve_min_V and valve_max_V"),
])
def test_impossible_rig_files_are_refused_naming_the_parameter_and_range(tmp_path, old, new, field, words):
    path = _rig_file(tmp_path, old, new)
    with pytest.raises(InputFileError) as err:
        load_rig(path)
    message = str(err.value)
    assert str(path) in message and field in message and words in message and "\n" not in message


@pytest.mark.parametrize("name, value", [("friction_static_N", math.nan), ("moving_mass_kg", math.inf),
                                         ("position_adc_bits", 16.5), ("supply_Pa", 2.0e5),
                                         ("dead_volume_a_m3", 0.0)])
def test_overrides_are_checked_and_blamed_on_their_origin(name, value):
    rig = load_rig("paper1-mre")
    with pytest.raises(PneusimError) as err:
        rig.with_params({name: value}, origin="--param")
    message = str(err.value)
    assert message.startswith(f"--param {name}=") and rig.source not in message


def test_param_on_the_command_line_blames_the_option_not_the_rig_file(tmp_path, capsys):
    code = main(["simulate", "--rig", "paper1-mre", "--input", "steps", "--param", "moving_mass_kg=-3",
                 "--out", str(tmp_path / "x.csv")])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and "--param moving_mass_kg=-3.0" in err and "must be positive" in err
    assert "paper1-mre.toml" not in err


@pytest.mark.parametrize("effect, values, words", [
    ("valve_deadband", {"deadband_V": -0.1}, ">= 0"),
    ("transport_delay", {"delay_s": -0.01}, "in [0, 10]"),
    ("transport_delay", {"delay_s": 1e9}, "in [0, 10]"),
    ("valve_dynamics", {"damping": 0.0}, "> 0"),
    ("valve_dynamics", {"damping": -0.7}, "> 0"),
    ("heat_transfer", {"time_constant_s": 0.0}, "> 0"),
    ("valve_offset", {"offset_V": math.nan}, "finite"),
    ("leakage", {"conductance_kg_per_s_Pa": math.inf}, ">= 0"),
])
def test_effect_parameters_out_of_range_are_refused(effect, values, words):
    with pytest.raises(PneusimError) as err:
        make_effect(effect, **values)
    key = next(iter(values))
    assert f"effect {effect}: parameter {key} must be" in str(err.value) and words in str(err.value)


def test_a_rig_written_back_is_a_rig_file_that_rig_accepts(tmp_path, capsys):
    rig = load_rig("paper2-enfield").with_params({"moving_mass_kg": 2.25, "friction_coulomb_N": 12.5})
    path = write_rig(rig, tmp_path / "fitted.toml")
    again = load_rig(path)
    assert dict(again.params) == dict(rig.params) and again.sections == rig.sections
    out = tmp_path / "run.csv"
    assert main(["simulate", "--rig", str(path), "--input", "steps", "--duration", "1", "--out", str(out)]) == 0
    rec = read_recording(out)
    assert rec.metadata["rig_file"] == str(path) and rec.n_samples == 100
    # a fit's effects are written too, and a simulation on the rig file switches them on
    path = write_rig(rig, tmp_path / "fitted-deadband.toml", [make_effect("valve_deadband", deadband_V=0.25)])
    assert main(["simulate", "--rig", str(path), "--input", "steps", "--duration", "1", "--out", str(out)]) == 0
    assert read_recording(out).metadata["effects"] == "valve_deadband:deadband_V=0.25"


# ------------------------------------------------------------------ recordings against their rig
def _recording(tmp_path, name="rec.csv", rig="paper2-enfield", n=200, **change):
    t = np.arange(n) * 0.01
    cols = dict(time_s=t, valve_cmd_V=5.0 + np.sin(t), position_m=0.05 + 0.03 * np.sin(t),
                pressure_a_Pa=4e5 + 1e4 * np.sin(t), pressure_b_Pa=3.5e5 + 1e4 * np.cos(t))
    for key, (index, value) in change.items():
        cols[key] = cols[key].copy()
        cols[key][index] = value
    meta = {"format": "pneusim-recording/1", "sample_time_s": "0.01", "rig": rig, "loop": "open"}
    rec = Recording(**cols, metadata=meta)
    path = tmp_path / name
    write_recording(rec, path)
    return path


@pytest.mark.parametrize("change, words", [
    ({"valve_cmd_V": (17, 1e30)}, "valve_cmd_V"),
    ({"valve_cmd_V": (3, 25.0)}, "command range [0, 10] V"),
    ({"pressure_a_Pa": (slice(None), 3.7)}, "bar or kPa"),
    ({"pressure_b_Pa": (5, 9.0e5)}, "above the supply"),
])
def test_check_refuses_recordings_their_rig_cannot_have_made(tmp_path, capsys, change, words):
    path = _recording(tmp_path, **change)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and str(path) in err and "Traceback" not in err


def test_check_refuses_an_unknown_rig_and_accepts_its_rig_file(tmp_path, capsys):
    path = _recording(tmp_path, rig="no-such-rig")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "'rig: no-such-rig' is not a known rig" in err and "--rig" in err
    assert main(["check", str(path), "--rig", "paper2-enfield"]) == 0


def test_check_several_files_and_the_time_at_an_end_stop(tmp_path, capsys):
    good = _recording(tmp_path, "good.csv")
    stuck = _recording(tmp_path, "stuck.csv", position_m=(slice(0, 50), 0.0))   # 0.5 s at the retracted end
    bad = _recording(tmp_path, "bad.csv", valve_cmd_V=(0, 1e30))
    assert main(["check", str(good), str(stuck), str(bad)]) == 2
    captured = capsys.readouterr()
    assert "2 of 3 files valid" in captured.out and "bad.csv" in captured.err
    assert "time at an end stop: 0.5 s (25 % of the run; retracted 0.5 s, extended 0 s)" in captured.out
    stops = end_stop_time(read_recording(stuck), 0.3048)
    assert stops["retracted_s"] == pytest.approx(0.5) and stops["extended_s"] == 0.0


@pytest.mark.slow
def test_practice_recordings_are_plausible_for_their_rigs(shared_dir):
    files = sorted((shared_dir / "practice").glob("*.csv")) + sorted((shared_dir / "practice2").glob("*.csv"))
    assert len(files) > 40
    for path in files:
        rec = read_recording(path)
        check_plausible(rec, load_rig(rec.rig))   # raises on the first implausible sample


@pytest.mark.parametrize("change, words", [({"valve_cmd_V": (17, 1e30)}, "valve_cmd_V"),
                                           ({"pressure_a_Pa": (slice(None), 3.7)}, "bar or kPa")])
def test_fit_refuses_implausible_recordings_before_fitting(tmp_path, capsys, change, words):
    path = _recording(tmp_path, **change)
    assert main(["fit", str(path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_fit_says_when_its_rig_differs_from_the_recordings(tmp_path, capsys):
    def stop(*args, **kwargs):   # the warning must come before the (minutes-long) fit starts
        raise PneusimError("stopped before fitting")

    path = _recording(tmp_path, rig="paper1-mre", n=200)
    rec = read_recording(path)
    assert rec.rig == "paper1-mre"
    args = build_parser().parse_args(["fit", str(path), "--rig", "paper2-enfield"])
    args.func = functools.partial(fit_command.run, fit_recording=stop)
    assert run_command(args) == 2
    err = capsys.readouterr().err
    assert "warning: --rig paper2-enfield (paper2-enfield) differs from the rig the recording names" in err
    assert err.index("warning") < err.index("stopped before fitting")
