"""Checks every estimator runs on the model it returns (internal).

An estimate that is unstable, whose input-output part is numerically zero, or
whose parameters are not finite is still returned (it may be what the data
say), but never without a word: the sentences go to ``model.warnings`` and are
issued as :class:`~sysid.errors.SysidWarning`.  The fit to the estimation data
(``model.report["fit_percent"]``, MATLAB's "Fit to estimation data") is
computed here from the estimator's loss.
"""
from __future__ import annotations

import warnings as _warnings

import numpy as np

from .errors import SysidWarning

__all__ = ["finish", "problems", "growth_over", "GROWTH_LIMIT"]

GROWTH_LIMIT = 2.0
"""A discrete pole ``|z| > 1`` counts as unstable when ``|z|^N`` over the estimation record exceeds this."""


def growth_over(radius: float, n_samples: int) -> float:
    """``radius ** n_samples`` without overflow (inf when it would overflow)."""
    if radius <= 0.0:
        return 0.0
    e = n_samples * np.log(radius)
    return float(np.exp(e)) if e < 700 else float("inf")


def _poles_and_kind(model):
    if hasattr(model, "to_lti_continuous"):           # IDTF: s-plane
        return np.roots(model.den), "s"
    if hasattr(model, "A") and np.ndim(model.A) == 2:  # IDSS
        return np.linalg.eigvals(model.A), "z"
    return model.poles(), "z"                          # IDPoly


def problems(model, y, u, what: str) -> list[str]:
    """Sentences describing what is wrong with ``model`` estimated from ``y, u`` (empty if nothing)."""
    from .predict import as_idpoly
    out = []
    arrays = [np.asarray(getattr(model, n), float) for n in ("A", "B", "C", "D", "F", "K", "num", "den")
              if isinstance(getattr(model, n, None), np.ndarray)]
    if not all(np.all(np.isfinite(a)) for a in arrays):
        return [f"{what} has non-finite parameters (inf or NaN): the estimate is unusable; check the data "
                f"(scaling, constant or repeated signals) and the orders."]
    poles, kind = _poles_and_kind(model)
    N = int(np.size(y))
    if poles.size:
        if kind == "z":
            r = float(np.max(np.abs(poles)))
            g = growth_over(r, N)
            if r > 1.0 and g > GROWTH_LIMIT:
                grows = f"grows by {g:.3g}x" if np.isfinite(g) else "overflows"
                out.append(f"{what} is unstable: a pole has |z| = {r:.6g} > 1, so its simulated output {grows} "
                           f"over the {N} estimation samples (compare, simulate and "
                           f"to_scipy responses diverge); use it for prediction only, or re-estimate "
                           f"(other orders, enforce_stability=True where offered, or data recorded in open loop).")
        else:
            re = float(np.max(poles.real))
            if re > 0.0:
                out.append(f"{what} is unstable: a pole has real part {re:.6g} rad/s > 0.")
    try:
        b = np.asarray(as_idpoly(model).B, float)
    except Exception:  # noqa: BLE001 - conversion trouble is reported by the finite check above
        b = np.zeros(0)
    sy = float(np.std(y))
    su = float(np.sqrt(np.mean(np.asarray(u, float) ** 2)))
    if b.size and sy > 0 and su > 0 and float(np.max(np.abs(b))) * su <= 1e-10 * sy:
        out.append(f"{what} has B = 0 to working precision (largest |b| = {float(np.max(np.abs(b))):.3g}): "
                   f"its output does not depend on the input, so its simulation is only the initial-state response.")
    return out


def finish(model, data, what: str, focus: str = "prediction", fit=None):
    """Record the estimation fit and the problems of ``model`` (fitted on ``data``); warn about each; return it.

    ``fit`` (percent) overrides the fit computed from ``model.loss`` (mean squared error of ``focus``).
    """
    y = data.y
    sy = float(np.std(y))
    loss = float(getattr(model, "loss", float("nan")))
    if fit is None:
        fit = 100.0 * (1.0 - np.sqrt(loss) / sy) if (sy > 0 and np.isfinite(loss) and loss >= 0) else float("nan")
    model.report["fit_percent"] = float(fit)
    model.report["focus"] = focus
    msgs = problems(model, y, data.u, what)
    model.warnings = msgs
    for m in msgs:
        _warnings.warn(m, SysidWarning, stacklevel=4)
    return model
