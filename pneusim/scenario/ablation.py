"""Effect ablations: a paper scenario re-run with one effect of ``shared/spec/diagnosis.md`` switched on at a
time (low, typical, high magnitude), a few realistic combinations and a realistic rig, every identifier scored.

An ablation file is a sweep file (``pneusim sweep``) with an ``[ablation]`` table::

    [sweep]
    scenario = "paper2-multisine.toml"
    [ablation]
    metric = "fit_percent"                 # or "square_error" (paper 1: one-step square error per order)
    physical_levels = ["typical"]          # levels whose case also fits the physical model (nominal + effect)
    physical_duration_s = 30.0             # the physical fits' record (shorter: they are the expensive part)
    realistic_rig = "paper2-enfield-realistic"
    [[ablation.cases]]
    effect = "valve_deadband"
    level = "typical"
    params = { deadband_V = 0.25 }
    source = "where the magnitude comes from"
    [[ablation.combinations]]
    name = "valve as a whole"
    effects = ["valve_deadband:deadband_V=0.25", "valve_dynamics:natural_frequency_Hz=30"]
    source = "..."

:func:`prepare_ablation` turns the cases into sweep ``[[points]]`` (the ideal rig first); the physical model is
scored by two identifiers added to the scenario: ``physical (nominal model)`` (the nominal model fitted to data
that contain the effect) and ``physical (effect switched on)`` (the model with the effect, its parameters freed
from their true values where the fit can free them; a transport delay stays fixed at its true value).  They run
in separate, shorter points (``physical_duration_s``) at the ``physical_levels`` only.
:func:`write_ablation_report` writes ``ablation.md``, ``ablation.csv`` and ``ablation.png`` beside the sweep
table.
"""

from __future__ import annotations

import copy
import csv
import io
from pathlib import Path

import numpy as np

from ..errors import InputFileError, PneusimError
from ..model import EFFECTS, make_effect
from ..outputs import write_json_atomic, write_text_atomic
from ..plotting import save_figure
from ..rig import load_rig
from ..simulate import rig_effects
from .figures import pyplot
from .schema import set_dotted, validate_scenario

__all__ = ["prepare_ablation", "write_ablation_report", "ablation_matrix", "LEVELS", "PHYSICAL_NOMINAL",
           "PHYSICAL_EFFECT"]

LEVELS = ("low", "typical", "high")
PHYSICAL_NOMINAL = "physical (nominal model)"
PHYSICAL_EFFECT = "physical (effect switched on)"
_KEYS = {"metric", "physical_levels", "physical_duration_s", "realistic_rig", "cases", "combinations",
         "paper_label"}
_SCORED = ("rls", "arx", "armax", "ss", "tf")


def _fail(path, field, message):
    raise InputFileError(message, path=path, field=field)


def _effect_text(name: str, params: dict) -> str:
    return name + (":" + ",".join(f"{k}={v!r}" if not isinstance(v, str) else f"{k}={v}"
                                  for k, v in params.items()) if params else "")


def prepare_ablation(sweep: dict, table: dict, path) -> dict:
    """Check the ``[ablation]`` table and add its cases to ``sweep`` as points; returns the sweep.

    ``sweep['ablation']`` keeps the parsed table with ``case_points``: ``[(case, point)]``, which the sweep
    turns into ``labels``: ``{run_id: case}`` for the report once the runs' context is known.
    """
    path = str(path)
    metric, phys_levels, phys_dur = _check_options(table, path)
    spec = copy.deepcopy(sweep["scenario"])
    idents = spec["identifiers"]
    scored = [i for i, ident in enumerate(idents) if ident["kind"] in _SCORED]
    own_physical = [i for i, ident in enumerate(idents) if ident["kind"] == "physical_fit"]
    idents.append({"name": PHYSICAL_NOMINAL, "kind": "physical_fit", "model_effects": "none", "enabled": False,
                   "fit_starts": 1, "note": "the nominal model fitted to data that contain the effect"})
    idents.append({"name": PHYSICAL_EFFECT, "kind": "physical_fit", "model_effects": "scenario", "enabled": False,
                   "fit_starts": 1, "note": "the model with the effect switched on, its parameters fitted"})
    i_nom, i_eff = len(idents) - 2, len(idents) - 1
    spec = validate_scenario(spec, where=path)
    base = dict(sweep["base"])
    for i in own_physical:
        base[f"identifiers.{i}.enabled"] = False
    cases = _Cases(idents, phys_dur)
    ref_phys = [i_nom] if phys_levels else None       # no physical levels: no physical fit at all
    cases.add({"row": "ideal rig", "group": "reference", "effect": "", "level": "", "source": "the rig file, sensor "
               "noise only"}, [], physical=ref_phys)
    _add_effect_cases(cases, table.get("cases", []), path, phys_levels, [i_nom, i_eff])
    _add_combinations(cases, table.get("combinations", []), path, ref_phys)
    if table.get("realistic_rig") is not None:
        _add_realistic_rig(cases, table["realistic_rig"], path, ref_phys)
    # check every point against the scenario now (a bad effect names the ablation file, before any run)
    for case, point in cases.items:
        trial = copy.deepcopy(spec)
        for key, value in {**base, **point}.items():
            set_dotted(trial, key, value, where=path)
        validate_scenario(trial, where=f"{path} ({case['row']}, {case['part']})")
    sweep = dict(sweep, scenario=spec, base=base, points=list(sweep.get("points", [])) + [p for _, p in cases.items])
    scored_names = [idents[i]["name"] for i in scored if idents[i].get("enabled", True)]
    sweep["ablation"] = {"metric": metric, "physical_levels": phys_levels, "physical_duration_s": phys_dur,
                         "case_points": list(cases.items), "rows": [c for c, _ in cases.items if c["part"] == "black-box"],
                         "identifiers": scored_names, "kinds": {i["name"]: i["kind"] for i in idents},
                         "published": {i["name"]: i.get("published", {}) for i in idents},
                         "duration_s": base.get("experiment.duration_s", spec["experiment"]["duration_s"]),
                         "scenario_name": spec["scenario"]["name"],
                         "paper_label": table.get("paper_label", "paper")}
    return sweep


def _check_options(table, path: str) -> tuple:
    """``(metric, physical_levels, physical_duration_s)`` of the ``[ablation]`` table, its keys checked."""
    if not isinstance(table, dict):
        _fail(path, "ablation", "expected a table")
    for key in sorted(set(table) - _KEYS):
        _fail(path, f"ablation.{key}", f"unknown key; expected one of {', '.join(sorted(_KEYS))}")
    metric = table.get("metric", "fit_percent")
    if metric not in ("fit_percent", "square_error"):
        _fail(path, "ablation.metric", f"expected 'fit_percent' or 'square_error', got {metric!r}")
    phys_levels = table.get("physical_levels", ["typical"])
    if not isinstance(phys_levels, list) or any(lv not in LEVELS for lv in phys_levels):
        _fail(path, "ablation.physical_levels", f"expected a list of {', '.join(LEVELS)}, got {phys_levels!r}")
    phys_dur = table.get("physical_duration_s")
    if phys_dur is not None and (isinstance(phys_dur, bool) or not isinstance(phys_dur, (int, float))
                                 or phys_dur <= 0):
        _fail(path, "ablation.physical_duration_s", f"expected a positive duration in s, got {phys_dur!r}")
    return metric, phys_levels, phys_dur


class _Cases:
    """The ablation's cases as ``(label, sweep point)`` pairs: each case's black-box point and, where asked,
    its physical point (only the physical identifiers, on the shorter record)."""

    def __init__(self, idents: list, phys_dur):
        self.items = []
        self.phys_base = {f"identifiers.{i}.enabled": False for i, ident in enumerate(idents)
                          if ident["kind"] != "physical_fit" and ident.get("enabled", True)}
        if phys_dur is not None:
            self.phys_base["experiment.duration_s"] = float(phys_dur)

    def add(self, case: dict, effects: list, physical=None, rig=None) -> None:
        point = {"rig.effects": list(effects)}
        if rig is not None:
            point["rig.name"] = rig
        self.items.append((dict(case, part="black-box"), point))
        if physical:
            p = {**point, **self.phys_base}
            for i in physical:
                p[f"identifiers.{i}.enabled"] = True
            self.items.append((dict(case, part="physical"), p))


def _add_effect_cases(cases: _Cases, raw_cases, path: str, phys_levels: list, physical: list) -> None:
    """``[[ablation.cases]]``: one effect of the vocabulary at a level, its parameters and their source."""
    if not isinstance(raw_cases, list) or not raw_cases:
        _fail(path, "ablation.cases", "expected at least one [[ablation.cases]] table")
    for k, case in enumerate(raw_cases):
        where = f"ablation.cases[{k}]"
        if not isinstance(case, dict):
            _fail(path, where, "expected a table")
        for key in sorted(set(case) - {"effect", "level", "params", "source"}):
            _fail(path, f"{where}.{key}", "unknown key; expected effect, level, params, source")
        name, level = case.get("effect"), case.get("level")
        if name not in EFFECTS:
            _fail(path, f"{where}.effect", f"expected one of {', '.join(EFFECTS)}, got {name!r}")
        if level not in LEVELS:
            _fail(path, f"{where}.level", f"expected one of {', '.join(LEVELS)}, got {level!r}")
        params = case.get("params", {})
        if not isinstance(params, dict):
            _fail(path, f"{where}.params", "expected a table PARAM = value")
        try:
            make_effect(name, **params)
        except PneusimError as exc:
            _fail(path, f"{where}.params", str(exc))
        if not isinstance(case.get("source", ""), str) or not case.get("source"):
            _fail(path, f"{where}.source", "expected a string saying where the magnitude comes from")
        text = _effect_text(name, params)
        cases.add({"row": f"{name} ({level})", "group": name, "effect": name, "level": level, "effects": [text],
                   "source": case["source"], "params": params}, [text],
                  physical=physical if level in phys_levels else None)


def _add_combinations(cases: _Cases, combinations, path: str, physical) -> None:
    """``[[ablation.combinations]]``: several effects at once, named."""
    for k, comb in enumerate(combinations):
        where = f"ablation.combinations[{k}]"
        if not isinstance(comb, dict) or not isinstance(comb.get("name"), str):
            _fail(path, f"{where}.name", "expected a table with a string name")
        for key in sorted(set(comb) - {"name", "effects", "source"}):
            _fail(path, f"{where}.{key}", "unknown key; expected name, effects, source")
        effects = comb.get("effects")
        if not isinstance(effects, list) or not effects or not all(isinstance(e, str) for e in effects):
            _fail(path, f"{where}.effects", "expected a non-empty list of 'NAME:PARAM=VALUE,...' strings")
        cases.add({"row": comb["name"], "group": "combination", "effect": "", "level": "", "effects": effects,
                   "source": comb.get("source", "")}, effects, physical=physical)


def _add_realistic_rig(cases: _Cases, rig, path: str, physical) -> None:
    """``realistic_rig``: the scenario on a rig variant file (a path relative to the ablation file)."""
    if not isinstance(rig, str):
        _fail(path, "ablation.realistic_rig", "expected a rig name or rig file path")
    rig_path = rig
    if rig.endswith(".toml") and not Path(rig).is_absolute():
        rig_path = str((Path(path).parent / rig).resolve())
    try:
        rrig = load_rig(rig_path)
        rig_effects(rrig)
    except PneusimError as exc:
        _fail(path, "ablation.realistic_rig", str(exc))
    cases.add({"row": f"realistic rig ({rrig.name})", "group": "reference", "effect": "", "level": "",
               "effects": list(rrig.effects), "source": f"{rrig.name}: every value justified in its rig file"},
              [], physical=physical, rig=rig_path)


def ablation_matrix(table: list[dict], ablation: dict) -> tuple[list, list, dict]:
    """``(rows, columns, values)``: case rows (paper and ideal rig first), identifier columns (then the two
    physical ones), ``values[(row, column)]`` = the metric, averaged over seeds."""
    metric = ablation["metric"]
    columns = list(ablation["identifiers"]) + [PHYSICAL_NOMINAL, PHYSICAL_EFFECT]
    acc = {}
    for r in table:
        case = ablation["labels"].get(r["run_id"])
        if case is None or r.get("status") != "ok" or r.get("identifier") not in columns:
            continue
        kind = ablation["kinds"].get(r["identifier"])
        if kind == "rls" and not str(r.get("reading", "")).startswith("online, 1-step"):
            continue
        m = metric if kind == "rls" else "fit_percent"
        if r.get(m) is None:
            continue
        acc.setdefault((case["row"], r["identifier"]), []).append(float(r[m]))
    values = {k: float(np.mean(v)) for k, v in acc.items()}
    paper = ablation["paper_label"]
    for c in columns:
        kind = ablation["kinds"].get(c)
        m = metric if kind == "rls" else "fit_percent"
        pub = ablation["published"].get(c, {}).get(m)
        if pub is not None:
            values[(paper, c)] = float(pub)
    rows = [paper] + [c["row"] for c in ablation["rows"]]
    return rows, columns, values


def _metric_of(ablation, column):
    return ablation["metric"] if ablation["kinds"].get(column) == "rls" else "fit_percent"


def _fmt(v, metric):
    if v is None or not np.isfinite(v):
        return "-"
    return f"{v:.3g}" if metric == "square_error" else f"{v:.1f}"


def write_ablation_report(table: list[dict], sweep: dict, out_dir) -> dict:
    """``ablation.csv`` (long: row, group, effect, level, identifier, metric, value, source), ``ablation.md``
    (the table effect x identifier with sources and computed findings) and ``ablation.png``."""
    out = Path(out_dir)
    ab = sweep["ablation"]
    rows, columns, values = ablation_matrix(table, ab)
    columns = [c for c in columns if any((r, c) in values for r in rows)]
    info = {c["row"]: c for c in ab["rows"]}
    fh = io.StringIO(newline="")      # the CSV text, written at once (atomically)
    w = csv.writer(fh)
    w.writerow(["row", "group", "effect", "level", "effects", "identifier", "metric", "value", "source"])
    for r in rows:
        c = info.get(r, {"group": "reference", "effect": "", "level": "", "effects": [],
                         "source": "the paper's published table"})
        for col in columns:
            if (r, col) in values:
                w.writerow([r, c["group"], c["effect"], c["level"], ";".join(c.get("effects", [])), col,
                            _metric_of(ab, col), repr(values[(r, col)]), c["source"]])
    write_text_atomic(out / "ablation.csv", fh.getvalue())
    ideal = {c: values.get(("ideal rig", c)) for c in columns}
    lines = [f"# Effect ablation: {ab['scenario_name']}", ""]
    sq = ab["metric"] == "square_error"
    lines.append(
        "Each row re-runs the scenario with one effect of `shared/spec/diagnosis.md` switched on (low, typical, "
        "high magnitude), a realistic combination, or a realistic rig; the ideal rig (sensor noise only) and the "
        "paper's published figures are the reference rows. "
        + ("RLS columns: one-step square error of the online estimator (output units squared, lower is better). "
           if sq else "Black-box columns: fit % on the validation half (higher is better). ")
        + f"Black-box rows use {ab['duration_s']:g} s records. Physical columns: fit % on the validation half of "
        + (f"a shorter {ab['physical_duration_s']:g} s record " if ab["physical_duration_s"] else "the record ")
        + f"(the fits are the expensive part), run only at the {', '.join(ab['physical_levels'])} magnitude, for "
        "the combinations, the ideal and the realistic rig: '" + PHYSICAL_NOMINAL + "' fits the nominal model "
        "to data that contain the effect; '" + PHYSICAL_EFFECT + "' fits the model with the effect switched on, "
        "its parameters freed from their true values (a transport delay stays fixed at its true value: it has "
        "no gradient).")
    lines.append("")
    header = ["case"] + columns + ["where the magnitude comes from"]
    lines.append("| " + " | ".join(header) + " |")
    lines.append("|" + "---|" * len(header))
    for r in rows:
        src = info.get(r, {}).get("source", "published table" if r == ab["paper_label"] else "")
        lines.append("| " + " | ".join([r] + [_fmt(values.get((r, c)), _metric_of(ab, c)) for c in columns]
                                       + [src.replace("|", "/")]) + " |")
    lines += ["", "## What each effect costs", ""]
    findings = _findings(rows, columns, values, ab, ideal)
    lines += [f"* {f}" for f in findings]
    lines += ["", "![ablation](ablation.png)", "",
              "Files: `ablation.csv` (long table with sources), `sweep.csv` (every identifier and reading), "
              "`runs/` (each run's result)."]
    write_text_atomic(out / "ablation.md", "\n".join(lines) + "\n")
    _figure(out / "ablation.png", rows, columns, values, ab)
    write_json_atomic(out / "ablation.json",
                      {"metric": ab["metric"], "rows": rows, "columns": columns,
                       "values": [{"row": r, "identifier": c, "value": v} for (r, c), v in values.items()],
                       "findings": findings}, indent=1)
    return {"rows": rows, "columns": columns, "values": values, "findings": findings}


def _findings(rows, columns, values, ab, ideal) -> list[str]:
    """Per effect: the largest change against the ideal rig at its high magnitude, computed."""
    out = []
    bb = [c for c in columns if c not in (PHYSICAL_NOMINAL, PHYSICAL_EFFECT)]
    effects = list(dict.fromkeys(c["effect"] for c in ab["rows"] if c["effect"]))
    for eff in effects:
        rs = {c["level"]: c["row"] for c in ab["rows"] if c["effect"] == eff}
        parts = []
        for level in LEVELS:
            row = rs.get(level)
            if row is None:
                continue
            deltas = []
            for c in bb:
                v, i = values.get((row, c)), ideal.get(c)
                if v is None or i is None:
                    continue
                deltas.append(v / i if _metric_of(ab, c) == "square_error" and i > 0 else v - i)
            if deltas:
                if ab["metric"] == "square_error" and any(ab["kinds"].get(c) == "rls" for c in bb):
                    parts.append(f"{level}: square error x{min(deltas):.2g} to x{max(deltas):.2g}")
                else:
                    parts.append(f"{level}: {min(deltas):+.1f} to {max(deltas):+.1f} points")
        typ = rs.get("typical")
        phys = ""
        if typ is not None and values.get((typ, PHYSICAL_NOMINAL)) is not None:
            phys = (f"; physical fit at the typical magnitude: nominal model {values[(typ, PHYSICAL_NOMINAL)]:.1f} %"
                    + (f", with the effect {values[(typ, PHYSICAL_EFFECT)]:.1f} %"
                       if values.get((typ, PHYSICAL_EFFECT)) is not None else ""))
        if parts:
            out.append(f"{eff}: black-box change against the ideal rig, " + "; ".join(parts) + phys + ".")
    return out


def _figure(path, rows, columns, values, ab):
    plt = pyplot()
    sq = ab["metric"] == "square_error"
    mat = np.full((len(rows), len(columns)), np.nan)
    for i, r in enumerate(rows):
        for j, c in enumerate(columns):
            v = values.get((r, c))
            if v is not None:
                mat[i, j] = v
    fig, axes = plt.subplots(1, 2 if sq else 1, figsize=(11 if sq else 9, 0.32 * len(rows) + 2), squeeze=False,
                             gridspec_kw={"width_ratios": [3, 2]} if sq else None, layout="constrained")
    rls_cols = [j for j, c in enumerate(columns) if _metric_of(ab, c) == "square_error"]
    fit_cols = [j for j, c in enumerate(columns) if j not in rls_cols]
    panels = ([(axes[0, 0], rls_cols, "one-step square error (log colour)"), (axes[0, 1], fit_cols, "fit %")]
              if sq else [(axes[0, 0], fit_cols, "fit % (validation)")])
    for ax, cols, title in panels:
        if not cols:
            ax.axis("off")
            continue
        sub = mat[:, cols]
        if title.startswith("one-step"):
            shown = np.log10(sub)
            im = ax.imshow(shown, aspect="auto", cmap="RdYlGn_r")
        else:
            im = ax.imshow(np.clip(sub, 0, 100), aspect="auto", cmap="RdYlGn", vmin=max(0, np.nanmin(sub) - 5)
                           if np.isfinite(np.nanmin(sub)) else 0, vmax=100)
        for i in range(sub.shape[0]):
            for j in range(sub.shape[1]):
                if np.isfinite(sub[i, j]):
                    ax.text(j, i, _fmt(sub[i, j], "square_error" if title.startswith("one-step") else "fit"),
                            ha="center", va="center", fontsize=6)
        ax.set_xticks(range(len(cols)), [columns[j] for j in cols], rotation=30, ha="right", fontsize=7)
        ax.set_yticks(range(len(rows)), rows, fontsize=7)
        ax.set_xlabel("model")
        ax.set_ylabel("rig case")
        ax.set_title(title, fontsize=9)
        fig.colorbar(im, ax=ax, fraction=0.04, label="log10 of the square error (output unit^2)"
                     if title.startswith("one-step") else "fit (%)")
    fig.suptitle(f"Effect ablation of {ab['scenario_name']}: how each model scores with one effect at a time "
                 "switched on in the rig (green: better)", fontsize=10)
    save_figure(fig, path)
