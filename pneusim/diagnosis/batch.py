"""Many recordings: each diagnosed in parallel (local processes or Dask, :mod:`pneusim.parallel`), one
summary table.

``diagnose_many(paths, out_dir)`` writes, per recording, ``OUT/STEM/`` (the report folder, when
reports are asked for) and ``OUT/STEM.json`` (the JSON result), and beside them ``OUT/summary.csv``
and ``OUT/summary.md``: one row per recording with its findings, nominal and final validation fit,
time and error.  A recording that fails (bad file, a fit that cannot start) is a row with its error;
the others go on.
"""

from __future__ import annotations

import csv
import json
import os
import time
import traceback
from pathlib import Path

from ..errors import PneusimError
from ..parallel import executor_map
from .diagnose import diagnose
from .report import write_report

__all__ = ["diagnose_many", "expand_recordings", "SUMMARY_COLUMNS"]

SUMMARY_COLUMNS = ("recording", "status", "findings", "nominal_fit_percent", "final_fit_percent",
                   "improvement_points", "mismatch_windows", "seconds", "error")

_SUFFIXES = (".csv", ".mat")


def expand_recordings(items) -> list[Path]:
    """Files as given, and the ``.csv``/``.mat`` recordings of any folder (sorted); a missing path is an error."""
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
    return out


def diagnose_one(path: str, rig, out_dir: str | None, report: bool, options: dict) -> dict:
    """Diagnose one recording in a worker; never raises (the row carries the error)."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    started = time.perf_counter()
    stem = Path(path).stem
    row = {"recording": Path(path).name, "status": "failed", "findings": "", "nominal_fit_percent": None,
           "final_fit_percent": None, "improvement_points": None, "mismatch_windows": None, "seconds": None,
           "error": None, "result": None}
    try:
        result = diagnose(path, rig, **options)
        d = result.to_dict()
        row.update(status="ok", findings=" ".join(result.effects) or "none",
                   nominal_fit_percent=d["nominal"]["fit_percent"], final_fit_percent=d["final_fit_percent"],
                   improvement_points=(d["final_fit_percent"] - d["nominal"]["fit_percent"]
                                       if d["final_fit_percent"] is not None and d["nominal"]["fit_percent"] is not None
                                       else None),
                   mismatch_windows=len(d["mismatch"]), result=d)
        if out_dir:
            Path(out_dir, f"{stem}.json").write_text(json.dumps(d, indent=1, allow_nan=False))
            if report:
                write_report(result, Path(out_dir) / stem)
    except PneusimError as exc:
        row["error"] = str(exc)
    except Exception as exc:  # noqa: BLE001 - one bad recording must not stop the others
        row["error"] = f"{type(exc).__name__}: {exc} ({traceback.format_exc(limit=2).splitlines()[-1]})"
    row["seconds"] = time.perf_counter() - started
    return row


def _lost(task, exc) -> dict:
    return {"recording": Path(task[0]).name, "status": "failed", "findings": "", "nominal_fit_percent": None,
            "final_fit_percent": None, "improvement_points": None, "mismatch_windows": None, "seconds": None,
            "error": f"the worker did not return: {type(exc).__name__}: {exc}", "result": None}


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
        One row per recording, in the order of ``paths`` (``result``: the JSON result, or None).
    """
    files = expand_recordings(paths)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if workers is None:
        workers = min(os.cpu_count() or 1, len(files))
    tasks = [(str(f), rig, str(out), report, options) for f in files]
    rows = {r["recording"]: r for r in executor_map(diagnose_one, tasks, _lost, workers, dask, progress,
                                                       desc="diagnose")}
    ordered = [rows[f.name] for f in files]
    write_summary(ordered, out)
    return ordered


def _cell(v):
    if isinstance(v, float):
        return f"{v:.6g}"
    return "" if v is None else str(v)


def write_summary(rows: list[dict], out_dir) -> Path:
    """``summary.csv`` and ``summary.md`` of :data:`SUMMARY_COLUMNS`."""
    out = Path(out_dir)
    with open(out / "summary.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(SUMMARY_COLUMNS)
        for r in rows:
            w.writerow([_cell(r.get(c)) for c in SUMMARY_COLUMNS])
    lines = ["| " + " | ".join(SUMMARY_COLUMNS) + " |", "|" + "---|" * len(SUMMARY_COLUMNS)]
    for r in rows:
        cells = []
        for c in SUMMARY_COLUMNS:
            v = _cell(r.get(c)).replace("|", "/")
            if c == "recording" and r.get("status") == "ok":
                v = f"[{v}]({Path(v).stem}/index.html)"
            cells.append(v)
        lines.append("| " + " | ".join(cells) + " |")
    (out / "summary.md").write_text("# Diagnosis summary\n\n" + "\n".join(lines) + "\n")
    return out / "summary.csv"
