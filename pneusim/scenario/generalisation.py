"""Generalisation: models trained on one operating condition, validated on others.

A scenario with ``[[conditions]]`` (schema in ``scenarios/README.md``) trains every identifier on its
main run, as usual, then re-runs the experiment under each condition (other rig parameters such as the
supply pressure or a payload mass, another signal such as a larger amplitude) and scores, without
re-identifying anything:

* every black-box model (ARX, ARMAX, state space, transfer function) simulated on the condition's
  whole record from estimated initial conditions (MATLAB ``compare``'s default);
* the fitted physical model, *told* the new condition as a user would be: a known parameter (supply
  pressure, sample time ...) is set to its new value; a fitted parameter (e.g. the moving mass) is
  shifted by the known change (``fitted + new - old``: "I added 3 kg"); it then re-runs the
  condition's experiment from its start without noise.

:func:`evaluate_conditions` returns the numbers; :func:`generalisation_blocks` turns them into report
blocks and figures.
"""

from __future__ import annotations

import copy

import numpy as np
import sysid

from ..metrics import error_stats
from ..signals import build_experiment, input_signal, output_signal
from ..simulate import simulate
from ..plotting import (Curve, compare_figure, fit_range, mark_clipped, model_styles, new_figure, parameter_axis,
                        save_figure)
from .figures import output_label, slug
from .identify import clean_row

__all__ = ["evaluate_conditions", "told_rig", "generalisation_blocks"]

_BLACKBOX = ("arx", "armax", "ss", "tf")


def told_rig(fitted_rig, true_rig, overrides: dict, fitted_names) -> tuple:
    """The fitted rig told a new condition: ``(rig, {name: value told})``.

    Parameters
    ----------
    fitted_rig : Rig
        The rig with the physical fit's estimates.
    true_rig : Rig
        The training condition's rig (what the user believes the change is relative to).
    overrides : dict
        The condition's ``rig_overrides`` (SI, true values).
    fitted_names : iterable of str
        Parameters the fit estimated: these are shifted by the change, the others are set.
    """
    told = {}
    for key, value in overrides.items():
        if key in fitted_names:
            told[key] = float(fitted_rig.params[key]) + float(value) - float(true_rig.params[key])
        else:
            told[key] = float(value)
    return fitted_rig.with_params(told), told


def evaluate_conditions(result, progress: bool = False) -> dict:
    """Score the trained models of ``result`` (a :class:`~pneusim.scenario.runner.ScenarioResult`) on every
    ``[[conditions]]`` of its scenario.

    Returns
    -------
    dict
        ``{"training": {identifier: fit % on the validation half}, "conditions": [{"name", "description",
        "rig_overrides", "told", "n_samples", "rows": [{identifier, kind, fit_percent, mse, ...}],
        "_t", "_y", "_yhat": {identifier: array}}]}`` (private ``_`` arrays for the figures).
    """
    spec, data = result.spec, result.spec["data"]
    rig, effects = result.rig, result.effects
    models = [r for r in result.rows if r.get("kind") in _BLACKBOX and r.get("_model") is not None]
    physical = [r for r in result.rows if r.get("kind") == "physical_fit" and r.get("_fit") is not None]
    training = {r["identifier"]: r.get("fit_percent") for r in models + physical}
    out = {"training": training, "conditions": []}
    for cond in spec.get("conditions", []):
        crig = rig.with_params(cond["rig_overrides"]) if cond["rig_overrides"] else rig
        cexp = copy.deepcopy(spec["experiment"])
        cexp.update(copy.deepcopy(cond["experiment"]))
        experiment, raw = build_experiment(crig, cexp)
        if experiment.sample_time_s != crig.sample_time_s:
            crig = crig.with_params({"sample_time_s": experiment.sample_time_s})
        sim = simulate(crig, experiment, effects, seed=int(cexp["seed"]), noise_scale=float(cexp["noise_scale"]),
                       progress=progress)
        rec = sim.recording
        y = output_signal(rec.position_m, crig, data)
        u = input_signal(rec.valve_cmd_V, raw, data)
        ts = experiment.sample_time_s
        d = sysid.iddata(y, u, ts)
        rows, yhats, told = [], {}, {}
        for r in models:
            try:
                yhat = np.asarray(sysid.simulate(r["_model"], d, initial="estimate"), float).ravel()
                rows.append({"identifier": r["identifier"], "kind": r["kind"], "status": "ok",
                             "reading": "trained on the main run, not re-identified", **error_stats(y, yhat)})
                yhats[r["identifier"]] = yhat
            except Exception as exc:  # noqa: BLE001 - one model failing must not stop the others
                rows.append({"identifier": r["identifier"], "kind": r["kind"], "status": "failed",
                             "reason": f"{type(exc).__name__}: {exc}"})
        for r in physical:
            fit = r["_fit"]
            try:
                trig, told = told_rig(fit.rig_, rig, cond["rig_overrides"], set(fit.parameters))
                psim = simulate(trig, experiment, fit.effects_, seed=int(cexp["seed"]), noise_scale=0.0)
                yhat = output_signal(psim.recording.position_m, crig, data)
                rows.append({"identifier": r["identifier"], "kind": r["kind"], "status": "ok",
                             "reading": "fitted on the main run, told the condition, experiment re-run",
                             "told": told, **error_stats(y, yhat)})
                yhats[r["identifier"]] = yhat
            except Exception as exc:  # noqa: BLE001
                rows.append({"identifier": r["identifier"], "kind": r["kind"], "status": "failed",
                             "reason": f"{type(exc).__name__}: {exc}"})
        out["conditions"].append({"name": cond["name"], "description": cond.get("description", ""),
                                  "rig_overrides": dict(cond["rig_overrides"]),
                                  "experiment": dict(cond["experiment"]), "told": told,
                                  "n_samples": int(rec.n_samples), "rows": rows,
                                  "_t": rec.time_s, "_y": y, "_yhat": yhats, "_recording": rec})
    return out


def clean_generalisation(gen: dict | None) -> dict | None:
    """The JSON part (no arrays, NaN as None)."""
    if gen is None:
        return None
    return {"training": {k: (v if v is None or np.isfinite(v) else None) for k, v in gen["training"].items()},
            "conditions": [{**{k: v for k, v in c.items() if not k.startswith("_") and k != "rows"},
                            "rows": [clean_row(r) for r in c["rows"]]} for c in gen["conditions"]]}


def _fmt(v):
    return "-" if v is None or not np.isfinite(v) else f"{v:.1f}"


def generalisation_blocks(result, out) -> list:
    """Report blocks: the table model x condition (fit %), a sentence per model, one figure per condition
    and a summary figure (written into ``out``)."""
    gen = result.generalisation
    if not gen or not gen["conditions"]:
        return []
    names = list(gen["training"])
    conds = gen["conditions"]
    fits = {c["name"]: {r["identifier"]: r.get("fit_percent") for r in c["rows"] if r["status"] == "ok"}
            for c in conds}
    header = ["model", "trained on (validation half)"] + [c["name"] for c in conds]
    body = [[n, _fmt(gen["training"][n])] + [_fmt(fits[c["name"]].get(n)) for c in conds] for n in names]
    blocks = [("h", (2, "Generalisation: trained on one condition, validated on others")),
              ("p", "Every model is trained once, on the main run (black-box models on its estimation half, the "
                    "physical model fitted on the same half). Each condition below re-runs the experiment on a "
                    "changed rig or with a changed signal; the black-box models are simulated on it as they are "
                    "(not re-identified), the physical model is told the change (a known parameter set to its "
                    "new value, a fitted one shifted by the known change) and re-runs the experiment. Fit % over "
                    "the condition's whole record; the first column is the usual validation fit on the training "
                    "condition."),
              ("ul", [_condition_item(c) for c in conds]),
              ("table", (header, body))]
    phys = [n for n in names if any(r.get("kind") == "physical_fit" for r in result.rows if r["identifier"] == n)]
    sentences = [text for c in conds if (text := _condition_sentence(c["name"], fits[c["name"]], gen, phys))]
    if sentences:
        blocks.append(("ul", sentences))
    unit = {"sensor_V": "V"}.get(result.spec["data"]["output_unit"], result.spec["data"]["output_unit"])
    ylabel = output_label(result.spec["data"]["output_unit"])
    kinds = {r["identifier"]: r.get("kind") for r in result.rows}
    for c in conds:
        name = f"generalisation-{slug(c['name'])}.png"
        _condition_figure(out / name, c, fits[c["name"]], unit, ylabel, kinds)
        blocks.append(("fig", (name, f"Condition '{c['name']}': measured output, each trained model's output "
                                     "(top, fit % in the legend), its error (bottom), both zoomed where the models "
                                     "miss most (right).")))
    _summary_figure(out / "generalisation.png", names, conds, fits, gen, kinds)
    blocks.append(("fig", ("generalisation.png", "Fit % of every model on the training condition and on each "
                                                 "unseen condition: the generalisation gap, one line per model.")))
    return blocks


def _condition_item(c: dict) -> str:
    """What a condition changes, and what the physical model was told, in the figures' engineering units."""
    what = ", ".join(_quantity(k, v) for k, v in c["rig_overrides"].items())
    told = ", ".join(_quantity(k, v) for k, v in c.get("told", {}).items())
    said = f"rig: {what}" + (f"; physical model told {told}" if told else "")
    return f"{c['name']}: {c['description'] or what}" + (f" ({said})" if what else "")


def _quantity(key: str, value_si: float) -> str:
    """A rig parameter's value in words and the unit the figures use (``supply pressure = 2 bar gauge`` for
    ``supply_Pa = 301325``, see :func:`pneusim.plotting.parameter_axis`)."""
    label, convert = parameter_axis(key)
    words, _, unit = label.rpartition(" (")
    unit = unit.removesuffix(")")
    shown = float(convert(value_si)) if convert is not None else float(value_si)
    return f"{words or key} = {shown:.4g}" + ("" if unit in ("", "-") else f" {unit}")


def _condition_sentence(name: str, f: dict, gen: dict, phys: list) -> str:
    """The black-box models' range on a condition, their largest drop, and the physical model's fit ("" when no
    black-box model scored)."""
    bb = {n: v for n, v in f.items() if n not in phys and v is not None and np.isfinite(v)}
    if not bb:
        return ""
    drops = {n: gen["training"][n] - v for n, v in bb.items() if gen["training"].get(n) is not None}
    worst = max(drops, key=drops.get) if drops else None
    text = f"{name}: the black-box models score {min(bb.values()):.1f}-{max(bb.values()):.1f} %"
    if worst is not None:
        text += f" (largest drop {drops[worst]:.1f} points, {worst})"
    for n in phys:
        if f.get(n) is not None:
            text += f"; the physical model {f[n]:.1f} % (trained {_fmt(gen['training'].get(n))} %)"
    return text + "."


def _condition_figure(path, c: dict, fits: dict, unit: str, ylabel: str, kinds: dict) -> None:
    """A condition's measured output and each trained model's output (top), their errors (bottom), both zoomed
    where the models miss most (right)."""
    curves = [Curve(n, yhat, fits.get(n), kinds.get(n)) for n, yhat in c["_yhat"].items()]
    fig, _ = compare_figure(c["_t"], c["_y"], curves, measured_label="measured (simulated rig)", ylabel=ylabel,
                            unit=unit, title=f"Condition '{c['name']}', never seen in training: each model trained on "
                                             "the main run, as it is (black box) or told the change (physical)")
    save_figure(fig, path)


def _summary_figure(path, names: list, conds: list, fits: dict, gen: dict, kinds: dict) -> None:
    """Fit % of every model on the training condition and on each condition, one line per model."""
    labels = ["training"] + [c["name"] for c in conds]
    values = {n: np.array([np.nan if v is None else v for v in
                           [gen["training"].get(n)] + [fits[c["name"]].get(n) for c in conds]], dtype=float)
              for n in names}
    low, high = fit_range([v for vals in values.values() for v in vals])
    fig, ax = new_figure(title="The generalisation gap: fit on the training condition and on conditions never "
                               "seen, each model trained once and never re-identified", size=(9, 4.4))
    styles = model_styles(names, [kinds.get(n) for n in names])
    x = np.arange(len(labels))
    clipped = 0
    for n in names:
        st = styles[n]
        gap = values[n][0] - np.nanmin(values[n][1:]) if len(labels) > 1 else np.nan
        ax.plot(x, values[n], marker=st["marker"], color=st["color"], ls=st["ls"], lw=1.2, ms=6,
                label=n + (f" (largest drop {gap:.1f} points)" if np.isfinite(gap) else ""))
    ax.set_ylim(low, high)
    for n in names:
        clipped += mark_clipped(ax, x, values[n], low, high, styles[n]["color"])
    if clipped:
        ax.set_title(f"{clipped} fit(s) below the range, marked by open triangles on the lower edge", fontsize=8)
    ax.set_xticks(x, labels, fontsize=8)
    ax.set_xlabel("operating condition")
    ax.set_ylabel("fit (%)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    save_figure(fig, path)
