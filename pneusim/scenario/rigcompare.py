"""Report blocks for ``[[rig_variants]]``: the scenario on the ideal rig, on each rig variant, and the paper.

Every sentence is computed from the rows, so it stays true when a key changes.
"""

from __future__ import annotations

import numpy as np

__all__ = ["rig_variant_blocks", "compared_rows", "ranking"]

_SCORED = ("rls", "arx", "armax", "ss", "tf", "physical_fit")


def _metric(row) -> str:
    return "square_error" if row.get("kind") == "rls" else "fit_percent"


def compared_rows(rows) -> dict:
    """``{identifier: (kind, metric, value)}`` of the rows a rig comparison shows (RLS: one step ahead)."""
    out = {}
    for r in rows:
        if r.get("kind") not in _SCORED or r.get("status") != "ok":
            continue
        if r.get("kind") == "rls" and r.get("horizon") != 1:
            continue
        m = _metric(r)
        out[r["identifier"]] = (r["kind"], m, r.get(m))
    return out


def ranking(values: dict, metric: str) -> list:
    """Identifiers best first (highest fit %, lowest square error); missing values left out."""
    ok = {k: v for k, v in values.items() if v is not None and np.isfinite(v)}
    return sorted(ok, key=ok.get, reverse=(metric == "fit_percent"))


def _fmt(v, metric):
    if v is None or not np.isfinite(v):
        return "-"
    return f"{v:.3g}" if metric == "square_error" else f"{v:.1f}"


def rig_variant_blocks(result) -> list:
    """A table identifier x (paper, this rig, each variant) and computed sentences on ranking and distance."""
    if not result.rig_variants:
        return []
    spec = result.spec
    published = {i["name"]: i.get("published", {}) for i in spec["identifiers"]}
    main = compared_rows(result.rows)
    variants = [(v, compared_rows(v["rows"])) for v in result.rig_variants]
    names = list(main)
    for _, rows in variants:
        names += [n for n in rows if n not in names]
    header = ["model", "metric", "paper", f"{result.rig_name} (this run)"] + [
        f"{v['name']} ({v['rig_name']})" for v, _ in variants]
    body = []
    for n in names:
        kind, metric, _ = main.get(n) or next(rows[n] for _, rows in variants if n in rows)
        pub = published.get(n, {}).get(metric)
        body.append([n, "one-step square error" if metric == "square_error" else "fit %", _fmt(pub, metric),
                     _fmt(main.get(n, (0, 0, None))[2], metric)]
                    + [_fmt(rows.get(n, (0, 0, None))[2], metric) for _, rows in variants])
    unit = {"sensor_V": "V"}.get(spec["data"]["output_unit"], spec["data"]["output_unit"])
    blocks = [("h", (2, "Ideal rig, realistic rig and the paper side by side")),
              ("p", "The same experiment, seed and identifiers on the ideal rig (sensor noise only) and on each rig "
                    "variant (its own effects and sensors), beside the paper's numbers. Square errors in "
                    f"{unit}^2; fit % on the validation half. The physical fit runs on a variant only where the "
                    "scenario asks for it (it is the expensive row).")]
    blocks.append(("ul", [f"{v['name']}: rig {v['rig_name']}; effects {', '.join(v['effects']) or 'none'}. "
                          f"{v['description']}" for v, _ in variants]))
    blocks.append(("table", (header, body)))
    sentences = []
    for metric in ("fit_percent", "square_error"):
        pub = {n: published.get(n, {}).get(metric) for n in names
               if (main.get(n) or (0, None))[1] == metric and published.get(n, {}).get(metric) is not None}
        if len(pub) < 2:
            continue
        pub_rank = ranking(pub, metric)
        what = "fit" if metric == "fit_percent" else "one-step square error"
        cols = [(f"{result.rig_name} (ideal)", main)] + [(v["name"], rows) for v, rows in variants]
        for label, rows in cols:
            vals = {n: rows[n][2] for n in pub if n in rows}
            rk = ranking(vals, metric)
            if not rk:
                continue
            same_best = rk[0] == pub_rank[0]
            if metric == "fit_percent":
                diffs = [vals[n] - pub[n] for n in vals if vals[n] is not None and np.isfinite(vals[n])]
                dist = f"ours minus the paper's {min(diffs):+.1f} to {max(diffs):+.1f} points"
            else:
                ratios = [vals[n] / pub[n] for n in vals if vals[n] is not None and np.isfinite(vals[n])]
                dist = f"ours / the paper's {min(ratios):.2g} to {max(ratios):.2g}"
            sentences.append(f"{label}: best {what} {rk[0]} (the paper's best: {pub_rank[0]}; "
                             f"{'same' if same_best else 'different'}); full ranking "
                             f"{'identical to' if rk == pub_rank else 'different from'} the paper's; {dist}.")
    if sentences:
        blocks.append(("ul", sentences))
    return blocks
