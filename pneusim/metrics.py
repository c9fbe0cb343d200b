"""Scores shared by the fit, the scenarios and the diagnosis."""

from __future__ import annotations

import numpy as np

__all__ = ["fit_percent"]


def fit_percent(y, yhat) -> float:
    """MATLAB ``compare`` fit, ``100 (1 - ||y - yhat|| / ||y - mean(y)||)`` over the finite samples [%]."""
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    ok = np.isfinite(y) & np.isfinite(yhat)
    y, yhat = y[ok], yhat[ok]
    den = np.linalg.norm(y - y.mean()) if y.size else 0.0
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / den)) if den > 0 else float("nan")
