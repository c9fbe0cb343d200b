"""Rig files: the shipped data sheets match shared/spec/rigs.toml; bad files get clear errors."""

import tomllib

import pytest

from pneusim.errors import InputFileError, PneusimError
from pneusim.rig import known_rig_names, known_stroke_m, load_rig


def test_shipped_rigs_match_the_data_sheets(shared_dir):
    sheets = tomllib.loads((shared_dir / "spec" / "rigs.toml").read_text())
    assert set(known_rig_names()) == set(sheets)
    for name, sheet in sheets.items():
        rig = load_rig(name)
        for section in ("known", "typical"):
            for key, value in sheet[section].items():
                assert rig.params[key] == pytest.approx(value), f"{name}.{section}.{key}"
            assert set(rig.sections[section]) == set(sheet[section])


def test_user_rig_file_copy_loads(tmp_path):
    text = load_rig("paper1-mre").source
    path = tmp_path / "my-rig.toml"
    path.write_text(open(text).read().replace('name = "paper1-mre"', 'name = "my-rig"')
                    .replace("moving_mass_kg = 0.35", "moving_mass_kg = 0.5"))
    rig = load_rig(path)
    assert rig.name == "my-rig" and rig["moving_mass_kg"] == 0.5
    assert known_stroke_m("paper1-mre") == 0.1 and known_stroke_m("my-rig") is None


@pytest.mark.parametrize("edit, field", [
    (("moving_mass_kg = 0.35", "moving_mass_kg = -1"), "moving_mass_kg"),
    (("moving_mass_kg = 0.35", 'moving_mass_kg = "heavy"'), "typical.moving_mass_kg"),
    (("bore_m = 0.027\n", ""), "known.bore_m"),
    (("valve_critical_pressure_ratio = 0.3", "valve_critical_pressure_ratio = 1.3"), "valve_critical_pressure_ratio"),
    (("[typical]", "[typicall]"), "typicall"),
])
def test_bad_rig_files_name_the_field(tmp_path, edit, field):
    source = open(load_rig("paper1-mre").source).read()
    assert edit[0] in source
    path = tmp_path / "bad.toml"
    path.write_text(source.replace(edit[0], edit[1]))
    with pytest.raises(InputFileError) as err:
        load_rig(path)
    assert str(path) in str(err.value) and field in str(err.value)


def test_unknown_rig_and_unknown_override():
    with pytest.raises(InputFileError, match="unknown rig"):
        load_rig("paper3")
    with pytest.raises(PneusimError, match="no parameter 'mass_kg'"):
        load_rig("paper1-mre").with_params({"mass_kg": 1.0})
    with pytest.raises(InputFileError, match="must be positive"):
        load_rig("paper1-mre").with_params({"stroke_m": 0.0})
