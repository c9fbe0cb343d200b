"""Report tables: the generic rows table and the papers' Table 1 layouts (``scenario.layout``)."""

from __future__ import annotations

import numpy as np

__all__ = ["layout_blocks", "rows_table", "fmt", "eq4_behaviour"]


def fmt(v, digits: int = 4) -> str:
    """A number for a table (``-`` for missing)."""
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    if isinstance(v, (int, np.integer)):
        return str(v)
    if isinstance(v, (float, np.floating)):
        return f"{v:.{digits}g}"
    return str(v)


def rows_table(rows, metrics):
    header = ["identifier", "reading", "status"] + list(metrics) + ["note"]
    body = []
    for r in rows:
        body.append([r["identifier"], r.get("reading", ""), r["status"]] + [fmt(r.get(m)) for m in metrics]
                    + [r.get("reason", "")])
    return header, body


def _ident(spec, name):
    return next(i for i in spec["identifiers"] if i["name"] == name)


def _paper1(result):
    spec, rows = result.spec, result.rows
    unit = spec["data"]["output_unit"]
    blocks = [("h", (2, "Table 1 layout: one-step prediction by model order (ours beside the paper's)")),
              ("p", f"Output in {unit}. Square error = mean squared one-step error ({unit}^2); "
                    "standard deviations of the actual output, the predicted output and the error. "
                    "Scored over the whole online run, including the estimator's convergence.")]
    header = ["T.F order", "signal", "min", "max", "square error", "std deviation",
              "paper min", "paper max", "paper square error", "paper std"]
    body = []
    one_step = sorted((r for r in rows if r.get("kind") == "rls" and r.get("horizon") == 1 and r["status"] == "ok"),
                      key=lambda r: r["order"])
    for r in one_step:
        pub = _ident(spec, r["identifier"]).get("published", {})
        for sig, key in (("Actual output", "actual"), ("Predicted model output", "predicted"), ("Error", "error")):
            first = sig == "Actual output"
            body.append([f"order {r['order']}" if first else "", sig, fmt(r[f"{key}_min"]), fmt(r[f"{key}_max"]),
                         fmt(r["square_error"]) if first else "", fmt(r[f"{key}_std"]),
                         fmt(pub.get(f"{key}_min")), fmt(pub.get(f"{key}_max")),
                         fmt(pub.get("square_error")) if first else "", fmt(pub.get(f"{key}_std")
                                                                           if key != "error" else pub.get("error_std"))])
    blocks.append(("table", (header, body)))
    steps = sorted((r for r in rows if r.get("kind") == "rls" and r["status"] == "ok"),
                   key=lambda r: (r["order"], r["horizon"]))
    multi = [r for r in steps if any(s["order"] == r["order"] and s["horizon"] > 1 for s in steps)]
    if multi:
        blocks += [("h", (2, "Effect of step prediction")),
                   ("table", (["order", "steps", "square error", "error std", "error min", "error max", "fit %"],
                              [[r["order"], r["horizon"], fmt(r["square_error"]), fmt(r["error_std"]),
                                fmt(r["error_min"]), fmt(r["error_max"]), fmt(r["fit_percent"])] for r in multi]))]
    pub = [r for r in rows if r.get("kind") == "published_z"]
    if pub:
        blocks += [("h", (2, "The published models (eqs. 9-11) on our data")),
                   ("p", "Fixed published coefficients predicting our simulated output one step ahead "
                         "(same data as the online rows) and run free from the first sample. Neither is ground "
                         "truth: they describe the paper's rig, ours is simulated."),
                   ("table", (["model", "reading", "square error", "error std", "one-step fit %",
                               "free-run fit %", "DC gain", "max |pole|"],
                              [[r["identifier"], r["reading"], fmt(r.get("square_error")), fmt(r.get("error_std")),
                                fmt(r.get("fit_percent")), fmt(r.get("free_run_fit_percent")), fmt(r.get("dc_gain")),
                                fmt(r.get("poles_abs_max"))] for r in pub]))]
    thetas = [r for r in one_step if r.get("theta_final")]
    if thetas:
        blocks += [("h", (3, "Final parameter vectors theta = [a1..an, b1..bn]")),
                   ("ul", [f"{r['identifier']}: [" + ", ".join(f"{v:.5g}" for v in r["theta_final"]) + "]"
                           for r in thetas])]
    blocks += _physical(rows)
    return blocks


def eq4_behaviour(r) -> str:
    """One sentence on what a reading of eq. 4 does over the record (computed, not asserted)."""
    if not r.get("stable", True):
        return "unstable"
    if r["delay_s"] >= 0.1 * r["record_s"]:
        return f"delay {r['delay_s']:g} s is {100 * r['delay_s'] / r['record_s']:.0f} % of the record"
    if r["slowest_time_constant_s"] > r["record_s"]:
        return (f"slowest time constant {r['slowest_time_constant_s']:.3g} s exceeds the {r['record_s']:g} s record: "
                "integrator-like over the record")
    return f"settles within the record (slowest time constant {r['slowest_time_constant_s']:.3g} s): type-0"


def _paper2(result):
    spec, rows = result.spec, result.rows
    blocks = [("h", (2, "Table 1 layout: best fit on the validation half (ours beside the paper's)")),
              ("p", "Fit % = 100 (1 - ||y - yhat|| / ||y - mean(y)||) of the simulated model output on the "
                    "validation half (MATLAB compare).")]
    body = []
    for r in rows:
        if r.get("kind") in ("arx", "armax", "ss", "tf", "physical_fit"):
            pub = _ident(spec, r["identifier"]).get("published", {})
            body.append([r["identifier"], fmt(pub.get("fit_percent")), fmt(r.get("fit_percent")), r["status"],
                         r.get("reason", "")])
    blocks.append(("table", (["model", "paper fit %", "our fit %", "status", "note"], body)))
    eq4 = [r for r in rows if r.get("kind") == "published_s"]
    if eq4:
        blocks += [("h", (2, "Equation 4 under three time-unit readings")),
                   ("p", "Equation 4 gives no time unit. Each reading rescales s and the delay to seconds, is "
                         "discretised (zero-order hold) at our sample time and simulated from rest on the validation "
                         "half. None of them is ground truth."),
                   ("table", (["reading", "delay (s)", "DC gain", "poles (rad/s)", "slowest time constant (s)",
                               "behaviour over the record", "fit %"],
                              [[r["reading"], fmt(r["delay_s"]), fmt(r["dc_gain"]),
                                "; ".join(_short_pole(p) for p in r["poles_rad_per_s"]),
                                fmt(r["slowest_time_constant_s"]), eq4_behaviour(r), fmt(r.get("fit_percent"))]
                               for r in eq4]))]
        blocks.append(("p", _physics_statement(eq4, result)))
    blocks += _physical(rows)
    return blocks


def _short_pole(text: str) -> str:
    p = complex(text)
    return f"{p.real:.3g}{p.imag:+.3g}j" if abs(p.imag) > 0 else f"{p.real:.3g}"


def _physics_statement(eq4, result) -> str:
    """Which reading the physics supports, from the computed numbers."""
    loop = result.spec["experiment"]["loop"]
    integ = [r["reading"] for r in eq4 if "integrator-like" in eq4_behaviour(r)]
    type0 = [r["reading"] for r in eq4 if "type-0" in eq4_behaviour(r)]
    delayed = [r["reading"] for r in eq4 if "of the record" in eq4_behaviour(r)]
    parts = []
    if delayed:
        parts.append(f"Read with {', '.join(delayed)}, the dead time is a large part of the {eq4[0]['record_s']:g} s "
                     "record, which no valve-cylinder rig shows.")
    if integ:
        parts.append(f"Read with {', '.join(integ)}, the model is integrator-like over the record, as a cylinder "
                     "driven directly by a valve command is (velocity follows the valve opening).")
    if type0:
        parts.append(f"Read with {', '.join(type0)}, it settles to a finite gain, as a position loop does, and the "
                     "paper's text ('15ms input-output delay') uses milliseconds.")
    poles = [complex(p) for p in eq4[0]["poles_rad_per_s"]]
    zetas = [-p.real / abs(p) for p in poles if abs(p.imag) > 0]
    parts.append(f"Our experiment is {loop}-loop, so the physics of our data supports a type-0 (position-loop) model "
                 "if closed and an integrator if open.")
    if zetas:
        parts.append(f"The complex pole pair of eq. 4 has a damping ratio of {min(zetas):.2g} in every reading "
                     "(rescaling time does not change it), a resonance neither a valve-driven cylinder nor a "
                     "proportional position loop shows at that level.")
    return " ".join(parts)


def _physical(rows):
    phys = [r for r in rows if r.get("kind") == "physical_fit"]
    if not phys:
        return []
    r = phys[0]
    if r["status"] != "ok":
        return [("h", (2, "Physical versus black-box")),
                ("p", f"Fitted physical model: {r['status']} ({r.get('reason', '')}).")]
    est = r.get("estimates", {})
    return [("h", (2, "Physical versus black-box")),
            ("p", f"Fitted physical model: fit {fmt(r.get('fit_percent'))} % on the validation half."),
            ("ul", [f"{k} = {v:.4g}" for k, v in est.items()])]


def layout_blocks(result):
    layout = result.spec["scenario"]["layout"]
    if layout == "paper1-table1":
        return _paper1(result)
    if layout == "paper2-table1":
        return _paper2(result)
    return []
