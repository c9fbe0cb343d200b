"""Many recordings: each diagnosed in parallel (local processes or Dask, :mod:`pneusim.parallel`), one
summary table.

``diagnose_many(paths, out_dir)`` writes, per recording, ``OUT/NAME/`` (the report folder, when
reports are asked for) and ``OUT/NAME.json`` (the JSON result), and beside them ``OUT/summary.csv``
and ``OUT/summary.md``: one row per recording with its findings, nominal and final validation fit,
time and error.  ``NAME`` is the recording's file stem; recordings whose stems collide (``sa/run.csv``
and ``sb/run.csv``, ``base.csv`` and ``base.mat``) get names that tell them apart
(:func:`output_names`), so no result replaces another.  A recording that fails (bad file, a rig it
cannot come from, a fit that cannot start) is a row with its error; the others go on.  Every file is
written atomically.
"""

from __future__ import annotations

import csv
import io
import os
import time
import traceback
from pathlib import Path

from ..errors import PneusimError
from ..outputs import MANIFEST, same_file, write_json_atomic, write_text_atomic
from ..parallel import executor_map
from ..plausibility import check_plausible, recording_rig
from ..recording import read_recording
from .diagnose import diagnose
from .report import write_report

__all__ = ["diagnose_many", "expand_recordings", "output_names", "SUMMARY_COLUMNS"]

SUMMARY_COLUMNS = ("recording", "status", "findings", "nominal_fit_percent", "final_fit_percent",
                   "improvement_points", "mismatch_windows", "seconds", "diagnosis_status", "diagnosis_search", "error")

_SUFFIXES = (".csv", ".mat")
#: names an output may not take (the folder's own files)
_RESERVED = {Path(MANIFEST).stem, "summary"}


def expand_recordings(items) -> list[Path]:
    """Files as given, and the ``.csv``/``.mat`` recordings of any folder (sorted); a missing path, or the
    same recording given twice (by two spellings, or as a file and within its folder), is an error."""
    out = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in _SUFFIXES and q.is_file())
            if not found:
                raise PneusimError(f"{p}: the folder holds no .csv or .mat recording")
            out += found
        elif p.is_file():
            out.append(p)
        else:
            raise PneusimError(f"{p}: no such file or folder")
    for i, p in enumerate(out):
        for q in out[:i]:
            if same_file(p, q):
                raise PneusimError(f"{p}: the same recording is given twice (also as {q}); each recording is "
                                   "diagnosed once")
    return out


def output_names(files) -> list[str]:
    """The name of each recording's outputs (``NAME.json``, ``NAME/``): its stem, made unique.

    Stems that collide take the suffix (``base-csv``, ``base-mat``) or, where that is not enough, the
    folders above them (``sa-run``, ``sb-run``); a name still taken gets a number.
    """
    files = [Path(f) for f in files]
    names = [f.stem for f in files]
    for stem in set(names):
        group = [i for i, n in enumerate(names) if n == stem]
        if len(group) < 2 and stem not in _RESERVED:
            continue
        with_suffix = [f"{stem}-{files[i].suffix.lstrip('.').lower()}" for i in group]
        if len(set(with_suffix)) == len(group) and stem not in _RESERVED:
            for i, n in zip(group, with_suffix):
                names[i] = n
            continue
        depth = 1
        while True:
            tried = ["-".join([*files[i].resolve().parent.parts[-depth:], files[i].stem]) for i in group]
            if len(set(tried)) == len(group) or depth > 20:
                break
            depth += 1
        for i, n in zip(group, tried):
            names[i] = n.lstrip("/-") or stem
    taken: set[str] = set()
    for i, n in enumerate(names):
        unique, k = n, 2
        while unique in taken or unique in _RESERVED:
            unique, k = f"{n}-{k}", k + 1
        names[i] = unique
        taken.add(unique)
    return names


def _labels(files) -> list[str]:
    """The ``recording`` column: the file's name, or the path as given where two share a name."""
    names = [Path(f).name for f in files]
    return [n if names.count(n) == 1 else str(f) for f, n in zip(files, names)]


def diagnose_one(path: str, rig, out_dir: str | None, report: bool, options: dict, name: str | None = None,
                 label: str | None = None) -> dict:
    """Diagnose one recording in a worker; never raises (the row carries the error).

    The recording is checked against its rig first (:func:`pneusim.plausibility.check_plausible`: the
    rig that made it, values it could have recorded); ``name`` names its outputs, ``label`` its row.
    """
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    started = time.perf_counter()
    name = name or Path(path).stem
    row = {"recording": label or Path(path).name, "name": name, "status": "failed", "findings": "",
           "nominal_fit_percent": None, "final_fit_percent": None, "improvement_points": None,
           "mismatch_windows": None, "seconds": None, "diagnosis_status": None, "diagnosis_search": None, "error": None,
           "result": None}
    try:
        recording = read_recording(path)
        rig_used = recording_rig(recording, rig, where=path)
        check_plausible(recording, rig_used)
        result = diagnose(recording, rig_used, **options)
        d = result.to_dict()
        row.update(status="ok", findings=" ".join(result.effects) or "none",
                   nominal_fit_percent=d["nominal"]["fit_percent"], final_fit_percent=d["final_fit_percent"],
                   improvement_points=(d["final_fit_percent"] - d["nominal"]["fit_percent"]
                                       if d["final_fit_percent"] is not None and d["nominal"]["fit_percent"] is not None
                                       else None),
                   mismatch_windows=len(d["mismatch"]), diagnosis_status=d.get("status", "complete"),
                   diagnosis_search=d.get("search"), result=d)
        if out_dir:
            write_json_atomic(Path(out_dir, f"{name}.json"), d, indent=1, allow_nan=False)
            if report:
                write_report(result, Path(out_dir) / name)
    except PneusimError as exc:
        row["error"] = str(exc)
    except Exception as exc:  # noqa: BLE001 - one bad recording must not stop the others
        row["error"] = f"{type(exc).__name__}: {exc} ({traceback.format_exc(limit=2).splitlines()[-1]})"
    row["seconds"] = time.perf_counter() - started
    return row


def _lost(task, exc) -> dict:
    path, name, label = task[0], task[5], task[6]
    return {"recording": label, "name": name, "status": "failed", "findings": "", "nominal_fit_percent": None,
            "final_fit_percent": None, "improvement_points": None, "mismatch_windows": None, "seconds": None,
            "error": f"the worker did not return: {type(exc).__name__}: {exc} ({path})", "result": None}


def diagnose_many(paths, out_dir, rig=None, *, workers: int | None = None, dask: str | None = None,
                  report: bool = True, progress: bool = True, **options) -> list[dict]:
    """Diagnose every recording of ``paths`` (files or folders) and write the summary table.

    Parameters
    ----------
    paths : sequence of path
    out_dir : path
        Folder of the per-recording results and of ``summary.csv`` / ``summary.md``.
    rig : str, optional
        Rig of every recording (default: each recording's metadata).
    workers : int, optional
        Local processes (default: CPU count; 0 runs in this process); Dask workers with ``dask="local"``.
    dask : str, optional
        ``"local"`` or a scheduler address: run on Dask (:func:`pneusim.parallel.executor_map`).
    report : bool
        Write each recording's report folder.
    **options
        Passed to :func:`pneusim.diagnose`.

    Returns
    -------
    list of dict
        One row per recording, in the order of ``paths`` (``result``: the JSON result, or None; ``name``:
        the name of its outputs).
    """
    files = expand_recordings(paths)
    names, labels = output_names(files), _labels(files)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if workers is None:
        workers = min(os.cpu_count() or 1, len(files))
    tasks = [(str(f), rig, str(out), report, options, n, lab) for f, n, lab in zip(files, names, labels)]
    rows = {r["name"]: r for r in executor_map(diagnose_one, tasks, _lost, workers, dask, progress,
                                               desc="diagnose")}
    ordered = [rows[n] for n in names]
    write_summary(ordered, out)
    return ordered


def _cell(v):
    if isinstance(v, float):
        return f"{v:.6g}"
    return "" if v is None else str(v)


def write_summary(rows: list[dict], out_dir) -> Path:
    """``summary.csv`` and ``summary.md`` of :data:`SUMMARY_COLUMNS` (each written atomically)."""
    out = Path(out_dir)
    text = io.StringIO(newline="")
    w = csv.writer(text)
    w.writerow(SUMMARY_COLUMNS)
    for r in rows:
        w.writerow([_cell(r.get(c)) for c in SUMMARY_COLUMNS])
    write_text_atomic(out / "summary.csv", text.getvalue())
    lines = ["| " + " | ".join(SUMMARY_COLUMNS) + " |", "|" + "---|" * len(SUMMARY_COLUMNS)]
    for r in rows:
        cells = []
        for c in SUMMARY_COLUMNS:
            v = _cell(r.get(c)).replace("|", "/")
            if c == "recording" and r.get("status") == "ok":
                v = f"[{v}]({r.get('name') or Path(v).stem}/index.html)"
            cells.append(v)
        lines.append("| " + " | ".join(cells) + " |")
    write_text_atomic(out / "summary.md", "# Diagnosis summary\n\n" + "\n".join(lines) + "\n")
    return out / "summary.csv"
