"""Scores shared by the fit, the scenarios and the diagnosis."""

from __future__ import annotations

import numpy as np

__all__ = ["fit_percent", "error_stats"]


def fit_percent(y, yhat) -> float:
    """MATLAB ``compare`` fit, ``100 (1 - ||y - yhat|| / ||y - mean(y)||)`` over the finite samples [%]."""
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    ok = np.isfinite(y) & np.isfinite(yhat)
    y, yhat = y[ok], yhat[ok]
    den = np.linalg.norm(y - y.mean()) if y.size else 0.0
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / den)) if den > 0 else float("nan")


def error_stats(y, yhat) -> dict:
    """Paper 1 Table 1 statistics: min, max, std of actual, predicted and error; mean square error.

    ``square_error`` is the mean of ``(y - yhat)^2`` over the finite samples, in output units squared.
    """
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    ok = np.isfinite(y) & np.isfinite(yhat)
    y, yhat = y[ok], yhat[ok]
    if not ok.any():
        nan = float("nan")
        return {"n_scored": 0, **{k: nan for k in ("square_error", "mse", "rmse", "error_std", "fit_percent")},
                **{f"{a}_{b}": nan for a in ("actual", "predicted", "error") for b in ("min", "max", "std")}}
    e = y - yhat
    out = {"n_scored": int(ok.sum()), "square_error": float(np.mean(e ** 2)), "mse": float(np.mean(e ** 2)),
           "rmse": float(np.sqrt(np.mean(e ** 2))), "error_std": float(np.std(e)), "fit_percent": fit_percent(y, yhat)}
    for name, v in (("actual", y), ("predicted", yhat), ("error", e)):
        out.update({f"{name}_min": float(v.min()), f"{name}_max": float(v.max()), f"{name}_std": float(np.std(v))})
    return out
