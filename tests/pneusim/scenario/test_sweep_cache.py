"""A sweep's stored runs are a cache keyed on everything that determines a run, written atomically and read
with care; a repeated seed or grid value is refused; a folder of another sweep is cleared with a message."""

import json
import shutil
from pathlib import Path

import pytest

from pneusim.cli import main
from pneusim.errors import InputFileError
from pneusim.outputs import MANIFEST
from pneusim.scenario.sweep import expand_runs, load_sweep, run_sweep

DATA = Path(__file__).with_name("data")


def _write(folder: Path, name: str, text: str) -> Path:
    p = folder / name
    p.write_text(text, encoding="utf-8")
    return p


def _sweep_text(base: str = "", grid: str = '"rig.overrides.moving_mass_kg" = [1.0, 1.5]', seeds="[0]",
                scenario="tiny.toml") -> str:
    return (f'[sweep]\nname = "s"\nscenario = "{scenario}"\nseeds = {seeds}\n[base]\n{base}\n'
            f"[grid]\n{grid}\n")


@pytest.fixture
def folder(tmp_path):
    shutil.copy(DATA / "tiny-open-loop.toml", tmp_path / "tiny.toml")
    return tmp_path


def _fits(table):
    return sorted((r["rig.overrides.moving_mass_kg"], r["identifier"], r["fit_percent"]) for r in table)


@pytest.mark.slow
def test_a_changed_base_or_scenario_runs_again_instead_of_reusing_old_results(folder):
    out = folder / "X"
    s1 = load_sweep(_write(folder, "s1.toml", _sweep_text('"experiment.duration_s" = 2.0')))
    first = run_sweep(s1, out, workers=0, progress=False)
    assert first["n_done_before"] == 0
    # the same varied keys and seed, another [base]: a different run, not the stored one
    s2 = load_sweep(_write(folder, "s2.toml", _sweep_text('"experiment.duration_s" = 3.0\n'
                                                          '"experiment.noise_scale" = 20.0')))
    second = run_sweep(s2, out, workers=0, progress=False)
    fresh = run_sweep(s2, folder / "fresh", workers=0, progress=False)
    assert second["n_done_before"] == 0
    assert _fits(second["table"]) == _fits(fresh["table"]) != _fits(first["table"])
    # the scenario file changed (same sweep file): its runs are run again too
    text = (folder / "tiny.toml").read_text().replace("forgetting = 0.98", "forgetting = 0.95")
    (folder / "tiny.toml").write_text(text)
    third = run_sweep(load_sweep(folder / "s2.toml"), out, workers=0, progress=False)
    assert third["n_done_before"] == 0
    # nothing changed: everything is reused
    again = run_sweep(load_sweep(folder / "s2.toml"), out, workers=0, progress=False)
    assert again["n_done_before"] == 2 and _fits(again["table"]) == _fits(third["table"])


def test_a_changed_rig_file_runs_again(folder):
    rig = folder / "r.toml"
    shutil.copy(Path(__file__).resolve().parents[3] / "pneusim" / "rigs" / "paper2-enfield.toml", rig)
    (folder / "tiny.toml").write_text((folder / "tiny.toml").read_text().replace('name = "paper2-enfield"',
                                                                                   'name = "r.toml"'))
    sweep = _write(folder, "s.toml", _sweep_text())
    out = folder / "X"
    run_sweep(load_sweep(sweep), out, workers=0, progress=False)
    assert "moving_mass_kg = 1.2\n" in rig.read_text()
    rig.write_text(rig.read_text().replace("moving_mass_kg = 1.2\n", "moving_mass_kg = 1.25\n"))
    info = run_sweep(load_sweep(sweep), out, workers=0, progress=False)
    assert info["n_done_before"] == 0


@pytest.mark.parametrize("content, words", [
    ('{"run_id": ', "not valid JSON"),
    ("{}", "lacks"),
    ("[1, 2]", "expected a JSON object"),
    ('{"run_id": "x", "params": {}, "seed": 0, "rows": "no", "error": null}', "lacks"),
])
def test_a_damaged_stored_run_is_run_again_with_a_note(folder, content, words, capsys):
    sweep = load_sweep(_write(folder, "s.toml", _sweep_text()))
    out = folder / "X"
    first = run_sweep(sweep, out, workers=0, progress=False)
    stored = sorted((out / "runs").glob("*.json"))
    stored[0].write_text(content)            # a crash while writing, or a hand edit
    info = run_sweep(sweep, out, workers=0, progress=False)
    assert info["n_done_before"] == 1 and _fits(info["table"]) == _fits(first["table"])
    assert any(words in note and stored[0].name in note for note in info["notes"])
    json.loads(stored[0].read_text())        # written again, whole


def test_runs_are_written_atomically(folder, monkeypatch):
    """A write that fails half-way leaves no file that a later resume would trip over."""
    import pneusim.outputs as outputs

    sweep = load_sweep(_write(folder, "s.toml", _sweep_text()))
    out = folder / "X"
    real = outputs.os.replace

    def crash(src, dst):
        if str(dst).endswith(".json") and "runs" in str(dst):
            raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(outputs.os, "replace", crash)
    with pytest.raises(OSError):
        run_sweep(sweep, out, workers=0, progress=False)
    monkeypatch.setattr(outputs.os, "replace", real)
    assert list((out / "runs").iterdir()) == []
    info = run_sweep(sweep, out, workers=0, progress=False)
    assert info["n_done_before"] == 0 and info["n_failed"] == 0


@pytest.mark.parametrize("sweep_text, field", [
    (_sweep_text(seeds="[0, 0]"), "sweep.seeds"),
    (_sweep_text(grid='"rig.overrides.moving_mass_kg" = [1.0, 1.0]'), "grid.rig.overrides.moving_mass_kg"),
    (_sweep_text(grid='"rig.overrides.moving_mass_kg" = [1.0, 1]'), "grid.rig.overrides.moving_mass_kg"),
    (_sweep_text() + '[[points]]\n"rig.overrides.moving_mass_kg" = 1.5\n', "points"),
])
def test_a_repeated_seed_grid_value_or_point_is_refused(folder, sweep_text, field):
    with pytest.raises(InputFileError) as err:
        load_sweep(_write(folder, "s.toml", sweep_text))
    assert err.value.field.startswith(field) and "twice" in str(err.value)


def test_random_draws_that_repeat_a_run_are_one_run(folder):
    text = (_sweep_text(grid="") + '[random]\nn = 6\nseed = 1\n'
            '"rig.overrides.moving_mass_kg" = { choices = [1.0, 1.5] }\n')
    sweep = load_sweep(_write(folder, "s.toml", text))
    runs = expand_runs(sweep)
    assert len(runs) == 2 and sweep["n_repeated"] == 4


def test_sweep_into_the_folder_of_another_sweep_clears_its_table_with_a_message(folder, capsys):
    out = folder / "X"
    s1 = _write(folder, "s1.toml", _sweep_text())
    s2 = _write(folder, "s2.toml", _sweep_text(grid='"experiment.noise_scale" = [0.5, 2.0]'))
    assert main(["sweep", str(s1), "--out", str(out), "--workers", "0", "--no-progress"]) == 0
    assert (out / "summary-rig.overrides.moving_mass_kg.png").exists()
    capsys.readouterr()
    assert main(["sweep", str(s2), "--out", str(out), "--workers", "0", "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "results of another run" in text and "s1.toml" in text
    # the other sweep's figure is gone (it would stand beside this sweep's table), its runs stay cached
    assert not (out / "summary-rig.overrides.moving_mass_kg.png").exists()
    assert (out / "summary-experiment.noise_scale.png").exists()
    assert len(list((out / "runs").glob("*.json"))) == 4
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["complete"] and "s2.toml" in manifest["command"]
    # the first sweep again: its runs come from the cache, nothing is run
    assert main(["sweep", str(s1), "--out", str(out), "--workers", "0", "--no-progress"]) == 0
    assert "2 runs (2 done before, 0 failed)" in capsys.readouterr().out
