"""Independent re-implementations used by the scenario tests to recompute the reports' numbers from
the written files.  Nothing here imports pneusim or sysid: plain loops and numpy, written apart from
the code under test."""

import csv

import numpy as np


def rows_of(metrics: dict, identifier: str) -> list:
    """The rows of ``metrics.json`` that belong to one identifier."""
    return [r for r in metrics["rows"] if r["identifier"] == identifier]


def read_predictions(path) -> dict:
    """predictions.csv as {column: float array} (empty cells as NaN), read with the csv module."""
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    return {name: np.array([float(r[i]) if r[i] != "" else np.nan for r in body]) for i, name in enumerate(header)}


def stats(y, yhat) -> dict:
    """Metrics of a row from the data and the model output (NaN samples left out)."""
    ok = ~np.isnan(y) & ~np.isnan(yhat)
    y, yhat = y[ok], yhat[ok]
    e = y - yhat
    out = {"n_scored": int(ok.sum()), "square_error": float(np.mean(e * e)), "mse": float(np.mean(e * e)),
           "error_std": float(np.std(e)),
           "fit_percent": float(100.0 * (1.0 - np.sqrt(np.sum(e * e)) / np.sqrt(np.sum((y - y.mean()) ** 2))))}
    for name, v in (("actual", y), ("predicted", yhat), ("error", e)):
        out.update({f"{name}_min": float(v.min()), f"{name}_max": float(v.max()), f"{name}_std": float(np.std(v))})
    return out


def rls_history(y, u, n, lam, c):
    """Textbook RLS (Ljung's gain-vector form) on phi(k) = [-y(k-1)..-y(k-n), u(k-1)..u(k-n)], zeros before
    the record; returns theta after each sample, shape (N, 2n)."""
    theta, P = np.zeros(2 * n), c * np.eye(2 * n)
    hist = np.zeros((len(y), 2 * n))
    for k in range(len(y)):
        phi = np.array([-(y[k - j] if k - j >= 0 else 0.0) for j in range(1, n + 1)]
                       + [(u[k - j] if k - j >= 0 else 0.0) for j in range(1, n + 1)])
        gain = P @ phi / (lam + phi @ P @ phi)
        theta = theta + gain * (y[k] - phi @ theta)
        P = (P - np.outer(gain, phi @ P)) / lam
        hist[k] = theta
    return hist


def h_step(y, u, thetas, n, h):
    """yhat(k | k-h): theta(k-h), measured y up to k-h, inputs up to k-1, iterated h times; NaN until
    k >= n + h."""
    out = np.full(len(y), np.nan)
    for k in range(n + h, len(y)):
        th = thetas[k - h]
        a, b = th[:n], th[n:]
        hist = {i: y[i] for i in range(k - h - n + 1, k - h + 1)}
        for j in range(k - h + 1, k + 1):
            hist[j] = sum(-a[i - 1] * hist[j - i] + b[i - 1] * u[j - i] for i in range(1, n + 1))
        out[k] = hist[k]
    return out


def arx_ls(y, u, na, nb, nk):
    """ARX by ordinary least squares on the samples with a full regressor; returns (A, B) in powers of
    z^-1 (B with nk leading zeros)."""
    start = max(na, nb + nk - 1)
    rows = [[-y[k - i] for i in range(1, na + 1)] + [u[k - nk - j] for j in range(nb)]
            for k in range(start, len(y))]
    theta, *_ = np.linalg.lstsq(np.array(rows), y[start:], rcond=None)
    return np.concatenate(([1.0], theta[:na])), np.concatenate((np.zeros(nk), theta[na:]))


def simulate_estimated_x0(num, den, u, y):
    """Zero-state simulation of num/den (powers of z^-1) by its difference equation, plus the free
    response (any solution of the homogeneous recurrence) that best fits y in least squares."""
    L = max(len(num), len(den))
    num = np.concatenate((num, np.zeros(L - len(num))))
    den = np.concatenate((den, np.zeros(L - len(den))))
    N, n = len(u), L - 1
    ys = np.zeros(N)
    for k in range(N):
        acc = sum(num[i] * u[k - i] for i in range(L) if k - i >= 0)
        acc -= sum(den[i] * ys[k - i] for i in range(1, L) if k - i >= 0)
        ys[k] = acc / den[0]
    basis = np.zeros((N, n))
    for j in range(n):
        h = np.zeros(N)
        h[j] = 1.0
        for k in range(n, N):
            h[k] = -sum(den[i] * h[k - i] for i in range(1, L)) / den[0]
        basis[:, j] = h
    if n:
        x0, *_ = np.linalg.lstsq(basis, y - ys, rcond=None)
        ys = ys + basis @ x0
    return ys
