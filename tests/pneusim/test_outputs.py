"""pneusim.outputs: atomic files, inputs never outputs, one run per results folder."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

import pneusim.outputs as outputs
from pneusim.errors import PneusimError
from pneusim.outputs import (MANIFEST, ResultsFolder, atomic_path, refuse_inputs_as_outputs, same_file,
                             savefig_atomic, write_json_atomic, write_text_atomic)


def test_an_atomic_write_replaces_the_file_whole_or_leaves_it(tmp_path, monkeypatch):
    target = tmp_path / "r.json"
    write_json_atomic(target, {"a": 1}, indent=1)
    assert json.loads(target.read_text()) == {"a": 1}

    def crash(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(outputs.os, "replace", crash)
    with pytest.raises(OSError):
        write_json_atomic(target, {"a": 2})
    assert json.loads(target.read_text()) == {"a": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]          # no temporary file left behind


def test_a_writer_that_raises_leaves_no_file(tmp_path):
    target = tmp_path / "c.npz"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            np.savez(tmp, x=np.arange(3))
            assert tmp.suffix == ".npz" and tmp.parent == tmp_path
            raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_writers_that_choose_the_format_by_the_suffix_write_the_same_bytes(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    undated = {"png": {}, "svg": {"Date": None}, "pdf": {"CreationDate": None}}
    for suffix, metadata in undated.items():
        with matplotlib.rc_context({"svg.hashsalt": "fixed"}):
            savefig_atomic(fig, tmp_path / f"a.{suffix}", metadata=metadata)
            fig.savefig(tmp_path / f"b.{suffix}", metadata=metadata)
        assert (tmp_path / f"a.{suffix}").read_bytes() == (tmp_path / f"b.{suffix}").read_bytes()
    plt.close(fig)
    with atomic_path(tmp_path / "c.npz") as tmp:
        np.savez(tmp, x=np.arange(3))
    assert np.load(tmp_path / "c.npz")["x"].tolist() == [0, 1, 2]


def test_text_keeps_its_permissions_and_newlines(tmp_path):
    target = write_text_atomic(tmp_path / "t.md", "a\nb\n")
    assert target.read_bytes() == b"a\nb\n"
    mask = os.umask(0)
    os.umask(mask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~mask


def test_an_input_is_never_an_output(tmp_path):
    a = tmp_path / "a.csv"
    a.write_text("x")
    os.link(a, tmp_path / "hard.csv")
    os.symlink(a, tmp_path / "soft.csv")
    for other in (a, tmp_path / "." / "a.csv", tmp_path / "hard.csv", tmp_path / "soft.csv"):
        assert same_file(other, a)
        with pytest.raises(PneusimError, match="--out .*the recording"):
            refuse_inputs_as_outputs({"--out": other}, {"the recording": a})
    assert not same_file(tmp_path / "new.csv", a) and same_file(tmp_path / "new.csv", tmp_path / "new.csv")
    refuse_inputs_as_outputs({"--out": tmp_path / "b.csv", "--plot": None}, {"the recording": a, "a rig": None})


def _run(folder: ResultsFolder, names: dict) -> list[str]:
    folder.prepare()
    for name, text in names.items():
        (folder.path / name).parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(folder.path / name, text)
    return folder.finish()


def test_a_folder_of_another_run_is_refused_and_the_same_run_replaces_its_own(tmp_path):
    out = tmp_path / "out"
    first = ResultsFolder(out, "--out", "pneusim run a.toml", {"a": 1}, known=("*.png", "report.md"))
    assert _run(first, {"report.md": "A", "fig-1.png": "1", "fig-2.png": "2"}) == ["fig-1.png", "fig-2.png",
                                                                                     "report.md"]
    (out / "mine.txt").write_text("the user's own file")
    other = ResultsFolder(out, "--out", "pneusim run b.toml", {"a": 2}, known=("*.png", "report.md"))
    with pytest.raises(PneusimError, match="another run: pneusim run a.toml .*--overwrite"):
        other.prepare()
    assert (out / "report.md").read_text() == "A"
    # the same run again: its files are replaced, the one it no longer writes removed, the user's kept
    again = ResultsFolder(out, "--out", "pneusim run a.toml", {"a": 1}, known=("*.png", "report.md"))
    assert _run(again, {"report.md": "A2", "fig-1.png": "1"}) == ["fig-1.png", "report.md"]
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "fig-1.png", "mine.txt", "report.md"])
    # --overwrite: the other run's files go first, with a note; the user's file stays
    forced = ResultsFolder(out, "--out", "pneusim run b.toml", {"a": 2}, overwrite=True, known=("*.png", "report.md"))
    notes = forced.prepare()
    assert "removed 2 file(s)" in notes[0] and sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "mine.txt"])


def test_policies_replace_and_measured(tmp_path):
    out = tmp_path / "sweep"
    _run(ResultsFolder(out, "--out", "s1", {"s": 1}, policy="replace", known=("sweep.csv",), keep=("runs",)),
         {"sweep.csv": "1", "runs/x.json": "{}"})
    notes = ResultsFolder(out, "--out", "s2", {"s": 2}, policy="replace", known=("sweep.csv",),
                          keep=("runs",)).prepare()
    assert "removed 1 file(s)" in notes[0] and (out / "runs" / "x.json").exists() and not (out / "sweep.csv").exists()
    mre = tmp_path / "mre"
    _run(ResultsFolder(mre, "--out", "m", policy="measured", known=("recording.csv",)), {"recording.csv": "x"})
    with pytest.raises(PneusimError, match="measured data are never replaced"):
        ResultsFolder(mre, "--out", "m", policy="measured", known=("recording.csv",)).prepare()


def test_a_folder_without_a_manifest_is_recognised_by_its_markers(tmp_path):
    out = tmp_path / "old"
    out.mkdir()
    (out / "metrics.json").write_text("{}")
    (out / "notes.txt").write_text("the user's")
    folder = ResultsFolder(out, "--out", "pneusim run a.toml", {"a": 1}, known=("metrics.json", "*.png"),
                           markers=("metrics.json",))
    with pytest.raises(PneusimError, match="older pneusim"):
        folder.prepare()
    # a folder of the user's files only is no other run's
    plain = tmp_path / "plain"
    plain.mkdir()
    (plain / "a.png").write_text("the user's picture")
    ResultsFolder(plain, "--out", "x", {"a": 1}, known=("metrics.json", "*.png"), markers=("metrics.json",)).prepare()
    assert (plain / "a.png").exists()


def test_a_manifest_never_removes_a_file_outside_its_folder_nor_an_input(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    (out / MANIFEST).write_text(json.dumps({"format": "pneusim-manifest/1", "command": "x", "identity": "z",
                                            "files": ["../victim.txt", "r.csv"]}))
    (out / "r.csv").write_text("input")
    folder = ResultsFolder(out, "--out", "y", {"a": 1}, overwrite=True, inputs={"the recording": out / "r.csv"})
    with pytest.raises(PneusimError, match="r.csv, the recording"):
        folder.prepare()
    ResultsFolder(out, "--out", "y", {"a": 1}, overwrite=True).prepare()
    assert victim.read_text() == "keep"


def test_a_file_the_run_would_replace_counts_as_another_runs(tmp_path):
    """No manifest, no marker, but a report.md of the user's where the run writes its report.md."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "report.md").write_text("# my notes")
    with pytest.raises(PneusimError, match="report.md; no pneusim-manifest.json"):
        ResultsFolder(out, "--out", "x", {"a": 1}, known=("report.md", "*.png"), markers=("metrics.json",)).prepare()
    assert (out / "report.md").read_text() == "# my notes"
