"""MATLAB-style display of identified models (internal): short matrices in full, large ones summarised."""
from __future__ import annotations

import numpy as np

__all__ = ["matrix_block", "status_block", "poly_text"]

MAX_SHOWN = 6
"""Matrices with more rows or columns than this are summarised instead of printed."""


def _num(v: float) -> str:
    return f"{v:.4g}"


def matrix_block(name: str, M: np.ndarray, rows: str, cols: str) -> list[str]:
    """``name = `` and the matrix with MATLAB's row/column labels, or a one-line summary if large."""
    M = np.atleast_2d(np.asarray(M, float))
    r, c = M.shape
    if r > MAX_SHOWN or c > MAX_SHOWN:
        extra = ""
        if r == c:
            lam = np.abs(np.linalg.eigvals(M))
            extra = f", eigenvalues |z| {lam.min():.4g} .. {lam.max():.4g}"
        return [f"  {name}: {r}x{c} matrix, entries {_num(M.min())} .. {_num(M.max())}{extra} "
                f"(model.{name} holds it)"]
    width = max(10, max(len(_num(v)) for v in M.ravel()) + 2)
    out = [f"  {name} = "]
    out.append(" " * 7 + "".join(f"{cols + str(k + 1):>{width}}" for k in range(c)))
    for i in range(r):
        out.append(f"   {rows}{i + 1:<3}" + "".join(f"{_num(v):>{width}}" for v in M[i]))
    return out


def poly_text(name: str, p: np.ndarray, var: str = "z^-1") -> str:
    """``A(z) = 1 - 1.5 z^-1 + 0.7 z^-2`` (coefficients in powers of ``z^-1``)."""
    terms = []
    for k, v in enumerate(np.asarray(p, float)):
        if v == 0.0 and not (k == 0 and p.size == 1):
            continue
        mag = _num(abs(v))
        pw = "" if k == 0 else (f" z^-{k}" if var == "z^-1" else "")
        t = f"{mag}{pw}"
        if not terms:
            terms.append(("-" if v < 0 else "") + t)
        else:
            terms.append(("- " if v < 0 else "+ ") + t)
    return f"  {name} = " + (" ".join(terms) if terms else "0")


def status_block(model, method: str, data_kind: str = "time domain data") -> list[str]:
    """``Status:`` lines: how it was estimated, fit to the estimation data, warnings."""
    rep = getattr(model, "report", {}) or {}
    out = ["Status:"]
    if getattr(model, "n_samples", 0):
        out.append(f"Estimated using {method} on {data_kind} ({model.n_samples} samples).")
        fit = rep.get("fit_percent")
        if fit is not None and np.isfinite(fit):
            out.append(f"Fit to estimation data: {fit:.2f}% ({rep.get('focus', 'prediction')} focus)")
        loss = getattr(model, "loss", float("nan"))
        if np.isfinite(loss):
            out.append(f"MSE: {loss:.4g}")
    else:
        out.append("Created by direct construction or transformation. Not estimated.")
    for w in getattr(model, "warnings", []) or []:
        out.append(f"Warning: {w}")
    return out
