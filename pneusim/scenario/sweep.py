"""Sweeps: vary scenario keys over a grid or random draws, run locally or on Dask, write one tidy table.

A sweep file (schema in ``scenarios/README.md``)::

    [sweep]
    scenario = "paper2-multisine.toml"   # relative to the sweep file
    seeds = [0, 1]                       # experiment.seed of each point (default: the scenario's)
    [base]                               # dotted-key overrides applied to every run
    "experiment.duration_s" = 5.0
    [grid]                               # Cartesian product of the lists
    "rig.overrides.supply_Pa" = [5e5, 6e5, 7e5]
    [random]                             # n draws, seeded, combined with every grid point
    n = 10
    seed = 0
    "rig.overrides.moving_mass_kg" = { low = 0.5, high = 2.0 }      # uniform (log = true: log-uniform)
    "identifiers.0.orders" = { choices = [[2, 2, 1], [3, 3, 1]] }
    [[points]]                           # extra points, appended as given
    "rig.overrides.moving_mass_kg" = 3.0

Every run is independent and seeded; its result is stored as
``OUT/runs/RUN_ID.json``, written atomically.  ``RUN_ID`` hashes everything
that determines the run (:mod:`pneusim.runid`): the varied parameters, the
seed, the scenario, ``[base]``, the sweep's options and the rig files they
name; so a restarted sweep skips the runs already done, and a sweep whose file,
scenario or rig changed runs its runs again instead of reusing old results.  A
stored run that cannot be read (a crash while writing, a hand edit) is run
again, with a note.  A seed, a grid value or a point listed twice is refused (it
would count one run twice); random draws that repeat a run are one run.  A run
that raises is recorded with its error and the sweep goes on.  The table
(``OUT/sweep.csv`` and ``OUT/sweep.parquet``) has one row per run and
identifier reading.
"""

from __future__ import annotations

import contextlib
import copy
import itertools
import json
import math
import multiprocessing
import os
import time
import tomllib
import traceback
import warnings
from pathlib import Path

import numpy as np

from ..errors import InputFileError, PneusimError
from ..outputs import atomic_path, write_json_atomic
from ..parallel import executor_map, local_pool
from ..plant import SimulatedPlant
from ..rig import load_rig
from ..runid import run_context, run_id
from ..simulate import merged_effects
from ..tomlfile import read_toml
from .ablation import prepare_ablation, write_ablation_report
from .identify import clean_row
from .runner import run_scenario
from .schema import load_scenario, set_dotted, validate_scenario
from .sweep_plots import summary_plots

__all__ = ["load_sweep", "expand_runs", "run_one", "run_sweep", "build_table", "write_table", "parse_set_items",
           "sweep_context", "sweep_run_id", "read_stored_run", "TABLE_METRICS"]

TABLE_METRICS = ("fit_percent", "mse", "rmse", "error_std", "square_error")


def parse_set_items(items) -> dict:
    """``["KEY=VALUE", ...]`` with VALUE read as a TOML value (bare words as strings)."""
    out = {}
    for item in items:
        key, eq, text = item.partition("=")
        if not eq or not key.strip():
            raise PneusimError(f"--set {item!r}: expected KEY=VALUE")
        try:
            out[key.strip()] = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = text
    return out


def load_sweep(path) -> dict:
    """Read a sweep file; returns ``{"name", "scenario": spec, "scenario_path", "base", "grid", "random",
    "seeds", "variants"}`` with every varied key checked against the scenario."""
    path = Path(path)
    data = read_toml(path, "sweep")
    unknown = sorted(set(data) - {"sweep", "base", "grid", "random", "points", "ablation"})
    if unknown:
        raise InputFileError("unknown table; expected sweep, base, grid, random, points, ablation", path=path,
                             field=unknown[0])
    points = data.get("points", [])
    if not isinstance(points, list) or not all(isinstance(p, dict) and p for p in points):
        raise InputFileError("expected [[points]] tables of dotted key = value", path=path, field="points")
    head = data.get("sweep", {})
    for key in sorted(set(head) - {"name", "scenario", "seeds", "variants"}):
        raise InputFileError("unknown key; expected name, scenario, seeds, variants", path=path, field=f"sweep.{key}")
    if not isinstance(head.get("scenario"), str):
        raise InputFileError("required: the scenario file (a string path)", path=path, field="sweep.scenario")
    scen_path = (path.parent / head["scenario"]).resolve()
    spec = load_scenario(scen_path)
    seeds = head.get("seeds", [spec["experiment"]["seed"]])
    if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds):
        raise InputFileError("expected a non-empty list of integers", path=path, field="sweep.seeds")
    _refuse_repeats(seeds, path, "sweep.seeds", "seed", "each seed gives one run per point")
    grid = data.get("grid", {})
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise InputFileError("expected a non-empty list of values", path=path, field=f"grid.{key}")
        _refuse_repeats(values, path, f"grid.{key}", "value", "each value gives one run per seed")
    rnd = dict(data.get("random", {}))
    n_rand = rnd.pop("n", 0 if not rnd else None)
    rnd_seed = rnd.pop("seed", 0)
    if n_rand is None or not isinstance(n_rand, int) or n_rand < 0:
        raise InputFileError("expected the number of random draws (integer >= 0)", path=path, field="random.n")
    for key, dist in rnd.items():
        ok = isinstance(dist, dict) and (("low" in dist and "high" in dist) or "choices" in dist)
        if not ok or set(dist) - {"low", "high", "log", "integer", "choices"}:
            raise InputFileError("expected { low = , high = [, log = true][, integer = true] } or { choices = [...] }",
                                 path=path, field=f"random.{key}")
        if "choices" in dist:
            if not isinstance(dist["choices"], list) or not dist["choices"]:
                raise InputFileError("expected a non-empty list of choices", path=path, field=f"random.{key}.choices")
            continue
        lo, hi = dist["low"], dist["high"]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (lo, hi)) or lo > hi:
            raise InputFileError(f"expected numbers low <= high, got low = {lo!r}, high = {hi!r}", path=path,
                                 field=f"random.{key}")
        if dist.get("log") and not lo > 0:
            raise InputFileError(f"log = true needs low > 0, got {lo!r}", path=path, field=f"random.{key}.low")
    if not isinstance(head.get("variants", False), bool):
        raise InputFileError("expected true or false", path=path, field="sweep.variants")
    if not isinstance(head.get("name", ""), str):
        raise InputFileError("expected a string", path=path, field="sweep.name")
    base = data.get("base", {})
    if not isinstance(base, dict) or not isinstance(grid, dict):
        raise InputFileError("expected a table of \"dotted.key\" = value", path=path,
                             field="base" if not isinstance(base, dict) else "grid")
    sweep = {"name": head.get("name", path.stem), "scenario": spec, "scenario_path": str(scen_path),
             "base": base, "grid": grid, "random": rnd, "n_random": n_rand, "random_seed": rnd_seed,
             "seeds": seeds, "variants": bool(head.get("variants", False)), "path": str(path), "points": points}
    sweep["context"] = sweep_context(sweep)
    _refuse_repeated_points(sweep, path)
    # validate the varied keys with the first run, naming the sweep file; an explicit point with a key the
    # scenario does not have is refused too, while a bad value only makes its run fail (recorded in the table)
    runs = expand_runs(sweep)
    for params, seed in runs[:1]:
        _apply(spec, sweep["base"], params, seed, where=str(path))
    for point in sweep["points"]:
        try:
            _apply(spec, sweep["base"], point, sweep["seeds"][0], where=str(path))
        except InputFileError as exc:
            if exc.reason.startswith(("unknown key", "unknown table", "unknown parameter", "cannot vary")):
                raise
    if "ablation" in data:      # an effect ablation: its cases become points (pneusim.scenario.ablation)
        sweep = prepare_ablation(sweep, data["ablation"], path)
        sweep["context"] = sweep_context(sweep)     # the ablation adds identifiers to the scenario
        sweep["ablation"]["labels"] = {sweep_run_id(sweep, point, seed): case
                                       for case, point in sweep["ablation"].pop("case_points")
                                       for seed in sweep["seeds"]}
    sweep["n_repeated"] = len(_all_runs(sweep)) - len(expand_runs(sweep))
    return sweep


def sweep_context(sweep: dict) -> str:
    """What every run of ``sweep`` shares, as a digest (:func:`pneusim.runid.run_context`): the scenario, the
    ``[base]`` overrides, the variants option and the rig files they name."""
    return run_context(sweep["scenario"], sweep["base"], {"variants": sweep["variants"]})


def sweep_run_id(sweep: dict, params: dict, seed: int) -> str:
    """The id of the run ``(params, seed)`` of ``sweep``: it changes with anything that changes the run."""
    return run_id(params, seed, sweep["context"])


def _refuse_repeats(values: list, path, field: str, what: str, why: str) -> None:
    """One line for the first value of ``values`` listed twice (``1`` and ``1.0`` are the same value)."""
    for i, v in enumerate(values):
        if any(v == w and type(v) is not bool for w in values[:i]):
            raise InputFileError(f"{what} {v!r} is listed twice; {why}, and a repeated one would count the same "
                                 "run twice", path=path, field=field)


def _refuse_repeated_points(sweep: dict, path) -> None:
    """An explicit ``[[points]]`` entry equal to a grid point or to an earlier point is refused."""
    keys = list(sweep["grid"])
    seen = [dict(zip(keys, combo)) for combo in itertools.product(*(sweep["grid"][k] for k in keys))] \
        if keys and not sweep["random"] else []
    for i, point in enumerate(sweep["points"]):
        if point in seen:
            raise InputFileError(f"{point} repeats a grid point or an earlier point (listed twice); it would "
                                 "count the same run twice", path=path, field=f"points[{i}]")
        seen.append(point)


def _draw(dist, rng):
    if "choices" in dist:
        return copy.deepcopy(dist["choices"][int(rng.integers(len(dist["choices"])))])
    lo, hi = float(dist["low"]), float(dist["high"])
    v = math.exp(rng.uniform(math.log(lo), math.log(hi))) if dist.get("log") else rng.uniform(lo, hi)
    return int(round(v)) if dist.get("integer") else float(v)


def expand_runs(sweep: dict) -> list[tuple[dict, int]]:
    """``[(params, seed)]``: (grid points x random draws, then the explicit points) x seeds, in a fixed order;
    a run that repeats an earlier one (random draws of the same choices) is listed once."""
    runs, seen = [], set()
    for params, seed in _all_runs(sweep):
        key = sweep_run_id(sweep, params, seed) if "context" in sweep else run_id(params, seed)
        if key not in seen:
            seen.add(key)
            runs.append((params, seed))
    return runs


def _all_runs(sweep: dict) -> list[tuple[dict, int]]:
    keys = list(sweep["grid"])
    points = [dict(zip(keys, combo)) for combo in itertools.product(*(sweep["grid"][k] for k in keys))] or [{}]
    if sweep["random"]:
        rng = np.random.default_rng(sweep["random_seed"])
        draws = [{k: _draw(d, rng) for k, d in sweep["random"].items()} for _ in range(sweep["n_random"])]
        points = [{**p, **d} for p in points for d in draws]
    if sweep.get("points"):
        points = ([] if points == [{}] else points) + [dict(p) for p in sweep["points"]]
    return [(p, s) for p in points for s in sweep["seeds"]]


def _apply(spec, base, params, seed, where="sweep"):
    spec = copy.deepcopy(spec)
    for key, value in {**base, **params}.items():
        set_dotted(spec, key, value, where=where)
    spec["experiment"]["seed"] = int(seed)
    return validate_scenario(spec, where=f"{where} (run {params}, seed {seed})")


def run_one(spec: dict, base: dict, params: dict, seed: int, variants: bool = False, rid: str | None = None) -> dict:
    """One sweep run (picklable, for any executor): never raises; errors are recorded in the result.

    ``rid`` is the run's id (:func:`sweep_run_id`; default: computed from these arguments)."""
    started, cpu_started = time.perf_counter(), time.process_time()
    if rid is None:
        rid = run_id(params, seed, run_context(spec, base, {"variants": variants}))
    out = {"run_id": rid, "params": params, "seed": seed, "rows": [], "error": None,
           "worker_pid": os.getpid()}
    with warnings.catch_warnings(record=True) as caught:      # kept with the run, not printed by every worker
        warnings.simplefilter("always")
        try:
            result = run_scenario(_apply(spec, base, params, seed), variants=variants)
            out["rows"] = [clean_row(r) for r in result.rows]
        except Exception as exc:  # noqa: BLE001 - a failed run is a result of the sweep
            out["error"] = f"{type(exc).__name__}: {exc}"
            out["traceback"] = traceback.format_exc(limit=5)
    out["warnings"] = sorted({f"{w.category.__name__}: {w.message} ({Path(w.filename).name}:{w.lineno})"
                              for w in caught})
    out["run_time_s"] = time.perf_counter() - started
    out["run_cpu_s"] = time.process_time() - cpu_started   # the run's own CPU time (a busy machine stretches run_time_s)
    return out


def _lost_run(task, exc) -> dict:
    """The result of a run whose worker did not return (it died, or the executor broke)."""
    _, _, params, seed, _, rid = task
    return {"run_id": rid, "params": params, "seed": seed, "rows": [], "worker_pid": None,
            "error": f"the worker did not return: {type(exc).__name__}: {exc}", "run_time_s": None}


def _warm_up(task) -> None:
    """Before local workers fork: build the model of the scenario's effects with its compiled kernels, here,
    once.  The workers fork at their first task and share it (copy-on-write), as they share every module
    imported here, instead of each building and generating it again."""
    spec, base, params, seed, _, _ = task
    try:
        spec = _apply(spec, base, params, seed)
        rig = load_rig(spec["rig"]["name"])
        if spec["rig"]["overrides"]:
            rig = rig.with_params(spec["rig"]["overrides"])
        SimulatedPlant(rig, merged_effects(rig, spec["rig"]["effects"]))
    except Exception:  # noqa: BLE001 - only a warm-up: the run itself reports what is wrong with it
        pass


def run_sweep(sweep: dict, out_dir, workers: int | None = None, dask: str | None = None, progress: bool = True,
              retry_failed: bool = False) -> dict:
    """Run every run not yet stored in ``out_dir/runs``, then write the table and plots.

    Parameters
    ----------
    workers : int or None
        Local processes (default: CPU count; 0 runs in this process); with
        ``dask = "local"`` the number of Dask workers.
    dask : str or None
        ``None`` (local processes), ``"local"`` (a loopback LocalCluster) or a scheduler address.

    Returns
    -------
    dict
        ``{"n_runs", "n_done_before", "n_failed", "wall_time_s", "runs_per_s", "table": [...rows],
        "notes": [...]}``; ``notes`` name the stored runs that could not be read and were run again.
    """
    out = Path(out_dir)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    if "context" not in sweep:
        sweep = dict(sweep, context=sweep_context(sweep))
    runs = expand_runs(sweep)
    ids = [sweep_run_id(sweep, params, seed) for params, seed in runs]
    todo, notes = [], []
    for (params, seed), rid in zip(runs, ids):
        f = out / "runs" / f"{rid}.json"
        if f.exists():
            done, problem = read_stored_run(f, rid)
            if problem:
                notes.append(f"{f}: {problem}; the run is run again")
            elif not (retry_failed and done.get("error")):
                continue
        todo.append((sweep["scenario"], sweep["base"], params, seed, sweep["variants"], rid))
    if workers is None:
        workers = os.cpu_count() or 1
    local = not dask and workers > 0
    with contextlib.ExitStack() as stack:
        pool = stack.enter_context(local_pool(workers)) if local else None
        started = time.perf_counter()
        if local and todo and multiprocessing.get_start_method() == "fork":
            _warm_up(todo[0])
        for res in executor_map(run_one, todo, _lost_run, workers, dask, progress, desc="sweep", pool=pool):
            write_json_atomic(out / "runs" / f"{res['run_id']}.json", res, allow_nan=False, default=str)
        wall = time.perf_counter() - started
        results = [_stored_or_fail(out / "runs" / f"{rid}.json", rid) for rid in ids]
        table = build_table(results)
        write_table(table, out)
        varied = list(dict.fromkeys(list(sweep["grid"]) + list(sweep["random"])
                                    + [k for p in sweep["points"] for k in p]))
        if pool is not None and workers > 1 and len(varied) > 1:
            # one figure per worker: drawing is the largest part of the sweep that is not the runs
            list(pool.map(summary_plots, [table] * len(varied), [[k] for k in varied], [out] * len(varied)))
        else:
            summary_plots(table, varied, out)
    if sweep.get("ablation"):
        write_ablation_report(table, sweep, out)
    return {"n_runs": len(runs), "n_done_before": len(runs) - len(todo), "n_failed": sum(bool(r["error"]) for r in results),
            "wall_time_s": wall, "runs_per_s": len(todo) / wall if todo and wall > 0 else float("nan"), "table": table,
            "notes": notes}


#: what a stored run holds (the rest, e.g. timings and warnings, is informative)
STORED_KEYS = {"run_id": str, "params": dict, "seed": int, "rows": list, "error": (str, type(None))}


def read_stored_run(path: Path, rid: str) -> tuple[dict | None, str | None]:
    """``(result, None)`` for a stored run that can be used, else ``(None, why not)``."""
    try:
        done = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        return None, f"not valid JSON ({exc})"
    if not isinstance(done, dict):
        return None, f"expected a JSON object, got {type(done).__name__}"
    for key, kind in STORED_KEYS.items():
        if key not in done or not isinstance(done[key], kind) or (kind is int and isinstance(done[key], bool)):
            return None, f"lacks a valid {key!r} (expected {getattr(kind, '__name__', 'a string or null')})"
    if done["run_id"] != rid:
        return None, f"holds run {done['run_id']!r}, not {rid!r}"
    return done, None


def _stored_or_fail(path: Path, rid: str) -> dict:
    done, problem = read_stored_run(path, rid)
    if problem:
        raise PneusimError(f"{path}: {problem} (written by this sweep a moment ago: another process writes there?)")
    return done


def _cell(v):
    if isinstance(v, (list, dict)):
        return json.dumps(v)
    return v


def build_table(results: list[dict]) -> list[dict]:
    """One row per run and identifier reading (one row with the error for a failed run); run order kept."""
    table = []
    for res in results:
        base = {"run_id": res["run_id"], "seed": res["seed"], **{k: _cell(v) for k, v in res["params"].items()}}
        if res["error"]:
            table.append({**base, "identifier": None, "reading": None, "status": "run failed", "error": res["error"],
                          **{m: None for m in TABLE_METRICS}, "identifier_time_s": None, "run_time_s": res["run_time_s"]})
            continue
        for r in res["rows"]:
            table.append({**base, "identifier": r["identifier"], "reading": r.get("reading", ""), "status": r["status"],
                          "error": r.get("reason"), **{m: r.get(m) for m in TABLE_METRICS},
                          "identifier_time_s": r.get("wall_time_s"), "run_time_s": res["run_time_s"]})
    return table


def write_table(table: list[dict], out_dir) -> None:
    """``sweep.csv`` and ``sweep.parquet`` (pyarrow; columns in first-seen order)."""
    # pyarrow takes about half a second to import; only the end of a sweep writes its table
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    columns = list(dict.fromkeys(k for row in table for k in row))
    data = {c: [row.get(c) for row in table] for c in columns}
    for c, values in data.items():
        kinds = {type(v) for v in values if v is not None}
        if len(kinds) > 1 and not kinds <= {int, float}:
            data[c] = [None if v is None else str(v) for v in values]
        elif kinds == {int, float}:
            data[c] = [None if v is None else float(v) for v in values]
    tab = pa.table(data) if table else pa.table({"run_id": pa.array([], pa.string())})
    out = Path(out_dir)
    with atomic_path(out / "sweep.parquet") as tmp:
        pq.write_table(tab, tmp)
    with atomic_path(out / "sweep.csv") as tmp:
        pacsv.write_csv(tab, tmp)
