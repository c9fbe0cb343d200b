"""Nothing lost, nothing overwritten, no wrong answer presented as right: the command line's outputs never
replace an input or another run's results, and a recording is only used with the rig that made it."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from pneusim.cli import main
from pneusim.outputs import MANIFEST
from pneusim.recording import read_recording, write_recording

from mre_cases import mre_text

ROOT = Path(__file__).resolve().parents[3]
SCENARIO = ROOT / "tests" / "pneusim" / "scenario" / "data" / "tiny-open-loop.toml"
SIM1 = ["simulate", "--rig", "paper1-mre", "--input", "steps", "--duration", "0.6"]
MRE_TEXT = mre_text(duration_s=0.3, seed=2)


def _last_error(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def _rig_copy(tmp_path: Path, mass: float = 3.0) -> Path:
    rig = tmp_path / "r.toml"
    text = (ROOT / "pneusim" / "rigs" / "paper2-enfield.toml").read_text()
    assert "moving_mass_kg = 1.2\n" in text
    rig.write_text(text.replace("moving_mass_kg = 1.2\n", f"moving_mass_kg = {mass}\n"))
    return rig


# ---------------------------------------------------------------- an output is never an input
def test_simulate_like_never_writes_over_the_recording_it_re_runs(tmp_path, capsys):
    p = tmp_path / "p.csv"
    assert main(SIM1 + ["--out", str(p)]) == 0
    before = p.read_bytes()
    os.link(p, tmp_path / "link.csv")
    for like, out in ((p, p), (p, tmp_path / "." / "p.csv"), (tmp_path / "link.csv", p)):
        capsys.readouterr()
        assert main(["simulate", "--like", str(like), "--out", str(out)]) == 2
        last = _last_error(capsys)
        assert "--out" in last and "--like" in last
    assert p.read_bytes() == before


def test_fit_never_writes_its_fitted_rig_over_the_rig_file_it_fits(tmp_path, capsys):
    rig = _rig_copy(tmp_path, mass=1.2)
    rec = tmp_path / "m.csv"
    assert main(["simulate", "--rig", str(rig), "--input", "steps", "--duration", "6", "--out", str(rec)]) == 0
    before = rig.read_bytes()
    capsys.readouterr()
    assert main(["fit", str(rec), "--rig", str(rig), "--rig-out", str(rig)]) == 2
    assert "--rig-out" in _last_error(capsys)
    assert main(["fit", str(rec), "--rig-out", str(rig)]) == 2          # the rig file the recording names
    assert "--rig-out" in _last_error(capsys) and rig.read_bytes() == before


def test_mre_never_clears_the_recording_it_replays(tmp_path, capsys):
    mre = tmp_path / "m.toml"
    mre.write_text(MRE_TEXT)
    out = tmp_path / "o"
    assert main(["mre", str(mre), "--fast", "--out", str(out), "--no-report"]) == 0
    replay = out / "recording.csv"
    before = replay.read_bytes()
    capsys.readouterr()
    assert main(["mre", str(mre), "--fast", "--plant", f"replay:{replay}", "--out", str(out), "--no-report",
                 "--overwrite"]) == 2
    assert "recording.csv" in _last_error(capsys) and replay.read_bytes() == before


def test_diagnose_refuses_a_report_folder_that_is_a_folder_of_its_recordings(tmp_path, capsys):
    folder = tmp_path / "recs"
    folder.mkdir()
    for name in ("a.csv", "b.csv"):
        assert main(SIM1 + ["--out", str(folder / name)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(folder), "--report", str(folder)]) == 2
    assert "--report" in _last_error(capsys) and sorted(p.name for p in folder.iterdir()) == ["a.csv", "b.csv"]


# ---------------------------------------------------------------- results folders
@pytest.mark.slow
def test_run_refuses_the_folder_of_another_run_and_replaces_its_own(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "results" / "tiny-open-loop"
    assert main(["run", str(SCENARIO), "--no-progress"]) == 0
    before = (folder / "metrics.json").read_bytes()
    capsys.readouterr()
    # the README's "pneusim run S --set ..." without --out: the results of another run are not replaced
    assert main(["run", str(SCENARIO), "--set", "experiment.duration_s=3", "--no-progress"]) == 2
    last = _last_error(capsys)
    assert "results/tiny-open-loop" in last and "another run" in last and "--overwrite" in last
    assert (folder / "metrics.json").read_bytes() == before
    # the same run again replaces its own results
    assert main(["run", str(SCENARIO), "--no-progress"]) == 0
    # --overwrite replaces the other run's, with a note
    capsys.readouterr()
    assert main(["run", str(SCENARIO), "--set", "experiment.duration_s=3", "--no-progress", "--overwrite"]) == 0
    assert "removed" in capsys.readouterr().out
    assert json.loads((folder / "metrics.json").read_text())["n_samples"] == 300
    manifest = json.loads((folder / MANIFEST).read_text())
    assert manifest["complete"] and "duration_s=3" in manifest["command"] and "metrics.json" in manifest["files"]


def test_run_refuses_a_folder_of_results_written_without_a_manifest(tmp_path, capsys):
    folder = tmp_path / "old"
    folder.mkdir()
    (folder / "report.md").write_text("# an older run\n")
    (folder / "metrics.json").write_text("{}")
    assert main(["run", str(SCENARIO), "--no-progress", "--out", str(folder)]) == 2
    assert "older pneusim" in _last_error(capsys)
    assert (folder / "report.md").read_text() == "# an older run\n"


@pytest.mark.slow
def test_mre_refuses_a_folder_holding_an_earlier_run_and_overwrite_clears_it(tmp_path, capsys):
    mre = tmp_path / "m.toml"
    mre.write_text(MRE_TEXT)
    out = tmp_path / "o"
    assert main(["mre", str(mre), "--fast", "--out", str(out)]) == 0
    assert (out / "report.md").exists() and list(out.glob("*.png"))
    before = (out / "recording.csv").read_bytes()
    capsys.readouterr()
    assert main(["mre", str(mre), "--fast", "--out", str(out), "--no-report", "--duration", "0.2"]) == 2
    last = _last_error(capsys)
    assert "earlier run" in last and "--overwrite" in last
    assert (out / "recording.csv").read_bytes() == before
    assert main(["mre", str(mre), "--fast", "--out", str(out), "--no-report", "--duration", "0.2",
                 "--overwrite"]) == 0
    # the old report and figures do not stand beside the new 200-sample recording
    assert not (out / "report.md").exists() and not list(out.glob("*.png"))
    assert read_recording(out / "recording.csv").n_samples == 200


# ---------------------------------------------------------------- diagnosis of several recordings
class _Result:
    """What diagnose_many needs of a diagnosis result, without the minutes of a real diagnosis."""

    def __init__(self, path):
        self.path = str(path)
        self.effects = ["valve_offset"]

    def to_dict(self):
        return {"recording": self.path, "nominal": {"fit_percent": 90.0}, "final_fit_percent": 95.0,
                "mismatch": []}


@pytest.fixture
def fake_diagnosis(monkeypatch):
    import pneusim.diagnosis.batch as batch

    def diagnose(recording, rig=None, **options):
        source = recording.source if hasattr(recording, "source") else recording
        if "bad" in str(source):
            raise batch.PneusimError(f"{source}: cannot be diagnosed")
        return _Result(source)

    def write_report(result, folder):
        Path(folder).mkdir(parents=True, exist_ok=True)
        (Path(folder) / "index.html").write_text(result.path)
        return Path(folder) / "index.html"

    monkeypatch.setattr(batch, "diagnose", diagnose)
    monkeypatch.setattr(batch, "write_report", write_report)


def test_diagnose_keeps_every_result_of_recordings_with_the_same_name(tmp_path, fake_diagnosis, capsys):
    for sub in ("sa", "sb"):
        (tmp_path / sub).mkdir()
        assert main(SIM1 + ["--out", str(tmp_path / sub / "run.csv")]) == 0
    assert main(SIM1 + ["--out", str(tmp_path / "base.csv")]) == 0
    assert main(SIM1 + ["--out", str(tmp_path / "base.mat")]) == 0
    files = [tmp_path / "sa" / "run.csv", tmp_path / "sb" / "run.csv", tmp_path / "base.csv", tmp_path / "base.mat"]
    out = tmp_path / "r"
    assert main(["diagnose", *map(str, files), "--report", str(out), "--workers", "0", "--quiet"]) == 0
    reports = sorted(p.read_text() for p in out.glob("*/index.html"))
    assert reports == sorted(map(str, files))                       # one report per recording, none replaced
    results = sorted(json.loads(p.read_text())["recording"] for p in out.glob("*.json") if p.name != MANIFEST)
    assert results == sorted(map(str, files))
    rows = (out / "summary.csv").read_text().splitlines()[1:]
    assert len(rows) == 4 and len(set(r.split(",")[0] for r in rows)) == 4


def test_diagnose_refuses_the_same_recording_given_twice(tmp_path, fake_diagnosis, capsys):
    rec = tmp_path / "a.csv"
    assert main(SIM1 + ["--out", str(rec)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(rec), str(tmp_path / "." / "a.csv"), "--report", str(tmp_path / "r")]) == 2
    assert "twice" in _last_error(capsys)


def test_diagnose_of_several_recordings_fails_when_one_fails(tmp_path, fake_diagnosis, capsys):
    folder = tmp_path / "recs"
    folder.mkdir()
    for name in ("good.csv", "bad1.csv", "bad2.csv"):
        assert main(SIM1 + ["--out", str(folder / name)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(folder), "--report", str(tmp_path / "r"), "--workers", "0", "--quiet"]) == 2
    assert "2 of 3 recordings failed" in _last_error(capsys)


# ---------------------------------------------------------------- the rig that made a recording
def test_a_recording_whose_rig_file_is_gone_or_changed_is_not_re_run_on_another_rig(tmp_path, capsys):
    rig = _rig_copy(tmp_path)
    rec = tmp_path / "m.csv"
    assert main(["simulate", "--rig", str(rig), "--input", "steps", "--duration", "2", "--out", str(rec)]) == 0
    moved = tmp_path / "moved.toml"
    rig.rename(moved)
    capsys.readouterr()
    for argv in (["simulate", "--like", str(rec), "--out", str(tmp_path / "m2.csv")], ["check", str(rec)],
                 ["fit", str(rec)]):
        assert main(argv) == 2
        last = _last_error(capsys)
        assert "rig_file" in last and "no longer exists" in last and "--rig" in last
    assert not (tmp_path / "m2.csv").exists()
    moved.write_text(moved.read_text().replace("moving_mass_kg = 3.0", "moving_mass_kg = 2.0"))
    moved.rename(rig)
    assert main(["simulate", "--like", str(rec), "--out", str(tmp_path / "m2.csv")]) == 2
    assert "changed since" in _last_error(capsys)
    # given explicitly, the rig file is used as it is now
    assert main(["simulate", "--like", str(rec), "--rig", str(rig), "--out", str(tmp_path / "m2.csv")]) == 0


def test_a_recording_of_another_rig_and_sample_time_is_refused_before_diagnosing(tmp_path, capsys):
    rec = tmp_path / "base1.csv"
    assert main(SIM1 + ["--out", str(rec)]) == 0          # paper1-mre, 1 ms
    capsys.readouterr()
    for argv in (["check", str(rec), "--rig", "paper2-enfield"], ["diagnose", str(rec), "--rig", "paper2-enfield"],
                 ["fit", str(rec), "--rig", "paper2-enfield"]):
        assert main(argv) == 2
        last = _last_error(capsys)
        assert "sample_time_s" in last and "paper1-mre" in last and "0.001" in last and "0.01" in last
    # the rig that made it, or the same rig at another sample time, is fine
    assert main(["check", str(rec), "--rig", "paper1-mre"]) == 0
    r = read_recording(rec)
    r.metadata["rig"] = "paper2-enfield"
    r.metadata.pop("rig_overrides", None)
    write_recording(r, tmp_path / "p2.csv")
    capsys.readouterr()
    assert main(["check", str(tmp_path / "p2.csv"), "--quiet"]) in (0, 2)
    assert "sample_time_s" not in capsys.readouterr().err


@pytest.mark.parametrize("key, value, words", [
    ("noise_scale", "-1", "noise_scale"),
    ("seed", "abc", "seed"),
    ("rig_overrides", "moving_mass_kg=-5", "moving_mass_kg"),
    ("effects", "no_such_effect", "no_such_effect"),
])
def test_check_refuses_the_metadata_that_simulate_like_refuses(tmp_path, capsys, key, value, words):
    rec = tmp_path / "p.csv"
    assert main(SIM1 + ["--out", str(rec)]) == 0
    r = read_recording(rec)
    r.metadata[key] = value
    bad = tmp_path / "bad.csv"
    write_recording(r, bad)
    capsys.readouterr()
    assert main(["simulate", "--like", str(bad), "--out", str(tmp_path / "x.csv")]) == 2
    like = _last_error(capsys)
    assert main(["check", str(bad)]) == 2
    check = _last_error(capsys)
    assert words in like and words in check


def test_fit_names_the_parameter_an_effect_does_not_have(tmp_path, capsys):
    from pneusim.errors import FitError
    from pneusim.fit.parameters import check_free

    names = ["friction_static_N", "valve_deadband.deadband_V"]
    with pytest.raises(FitError, match="valve_deadband has no parameter 'nosuch'.*deadband_V"):
        check_free(["valve_deadband.nosuch"], names)
    with pytest.raises(FitError, match="not switched on"):
        check_free(["leakage.area_m2"], names)
    with pytest.raises(FitError, match="no effect 'nosuch'"):
        check_free(["nosuch.x"], names)


def test_an_existing_results_file_is_replaced_whole_or_not_at_all(tmp_path, monkeypatch, capsys):
    """simulate --out over an existing recording: a write that fails leaves the old file whole."""
    import pneusim.outputs as outputs

    p = tmp_path / "p.csv"
    assert main(SIM1 + ["--out", str(p)]) == 0
    before = p.read_bytes()

    def full_disk(src, dst):
        raise OSError(28, "No space left on device", str(dst))

    monkeypatch.setattr(outputs.os, "replace", full_disk)
    assert main(SIM1 + ["--seed", "3", "--out", str(p)]) == 2
    assert "No space left" in _last_error(capsys)
    assert p.read_bytes() == before and sorted(x.name for x in tmp_path.iterdir()) == ["p.csv"]


def test_simulate_refuses_a_noise_scale_no_recording_can_hold(tmp_path, capsys):
    """Before simulating, naming the option (the recording itself used to be refused afterwards, naming a
    pressure sample)."""
    assert main(SIM1 + ["--noise-scale", "1e300", "--out", str(tmp_path / "n.csv")]) == 2
    last = _last_error(capsys)
    assert "--noise-scale = 1e+300" in last and "at most" in last and not (tmp_path / "n.csv").exists()


def test_mre_replay_of_another_rigs_recording_says_what_to_replay(tmp_path, capsys):
    """The README's ``--plant replay:run.csv`` with its paper-2 run.csv on the paper-1 MRE file."""
    run = tmp_path / "run.csv"
    assert main(["simulate", "--rig", "paper2-enfield", "--input", "steps", "--duration", "1", "--out", str(run)]) == 0
    mre = tmp_path / "m.toml"
    mre.write_text(MRE_TEXT)
    capsys.readouterr()
    assert main(["mre", str(mre), "--fast", "--plant", f"replay:{run}", "--out", str(tmp_path / "o")]) == 2
    last = _last_error(capsys)
    assert "paper2-enfield" in last and "paper1-mre" in last and "pneusim simulate --rig paper1-mre" in last


@pytest.mark.slow
def test_sigterm_stops_any_command_as_ctrl_c_does_and_leaves_no_partial_file(tmp_path):
    """A sweep stopped by SIGTERM: exit 143, every stored run whole, a restart reuses them."""
    import signal
    import subprocess
    import sys
    import time

    (tmp_path / "tiny.toml").write_text(SCENARIO.read_text())
    sweep = tmp_path / "s.toml"
    sweep.write_text(f'[sweep]\nname = "s"\nscenario = "tiny.toml"\nseeds = {list(range(40))}\n'
                     '[grid]\n"rig.overrides.moving_mass_kg" = [1.0, 1.2, 1.4, 1.6, 1.8]\n')
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "pneusim.cli", "sweep", str(sweep), "--out", str(out),
                             "--workers", "0", "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline = time.monotonic() + 120
        # stored runs only: the glob also matches a run being written (its hidden ".NAME.tmp.json")
        while time.monotonic() < deadline and len([p for p in (out / "runs").glob("*.json")
                                                    if not p.name.startswith(".")]) < 2:
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signal.SIGTERM and "terminated (SIGTERM)" in err and "Traceback" not in err
    stored = list((out / "runs").glob("*.json"))
    assert 2 <= len(stored) < 200 and all(json.loads(p.read_text())["run_id"] == p.stem for p in stored)
    assert all(not json.loads(p.read_text())["error"] for p in stored)      # the interrupt is no failed run
    assert not [p for p in out.rglob(".*") if ".tmp" in p.name]
    assert main(["sweep", str(sweep), "--out", str(out), "--workers", "0", "--no-progress"]) == 0
