"""The transport delay: a parameter without a gradient, estimated by scans.

A dead time moves the instants at which the valve sees each command; the model's response to it is a
step function of the delay between samples and has no useful derivative, so the fit keeps it fixed and
the diagnosis scans it twice:

1. **screening** -- a few fixed delays around the lag of the command-residual cross-correlation,
   each screened by trust-region steps from the nominal optimum; :func:`refine_from_screening` puts a
   parabola through the best gain and its neighbours;
2. **refits** -- once a delay is kept, :func:`scan_with_refits` refits the whole model at delays
   around it (each warm-started from the kept fit) and walks downhill in the estimation residual
   sum of squares, then a parabola in ``log(delay)`` through the best three.  Screening from the
   nominal fit's states favours the smaller delays (the states it starts from belong to no delay):
   on ``practice2_28`` (paper 1, a 12.5 ms delay) it kept 8 ms, 77.2 % validation.

Only the estimation part decides the delay; the validation part stays unseen.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..model import make_effect
from . import candidates as cand

__all__ = ["refine_from_screening", "scan_with_refits", "SCAN_FACTOR", "SCAN_REFITS"]

#: neighbouring delays of the refit scan differ by this factor
SCAN_FACTOR = 1.5
#: at most this many refits in the scan
SCAN_REFITS = 8


def _on_grid(delay_s: float, sample_time_s: float) -> float:
    """A delay rounded to a tenth of a sample, at least half a sample."""
    return float(max(0.5 * sample_time_s, round(delay_s / sample_time_s * 10) / 10 * sample_time_s))


def _parabola_in_log(delays, values, best: int) -> float | None:
    """The minimum (or maximum, for gains: pass ``-gain``) of a parabola through ``best`` and its two
    neighbours in ``log(delay)``; None without a neighbour on each side or without curvature."""
    if not 0 < best < len(delays) - 1:
        return None
    x = np.log(np.asarray(delays[best - 1:best + 2], float))
    y = np.asarray(values[best - 1:best + 2], float)
    if not np.all(np.isfinite(y)):
        return None
    a, b, _ = np.polyfit(x, y, 2)
    if a <= 0:
        return None
    return float(np.exp(np.clip(-b / (2 * a), x[0], x[-1])))


def refine_from_screening(scan, sample_time_s: float) -> float:
    """The delay of largest screening gain (``scan``: ``(delay_s, gain)`` pairs), refined by a parabola
    through it and its neighbours in ``log(delay)``."""
    scan = sorted(scan)
    d = [s[0] for s in scan]
    g = np.array([s[1] for s in scan], float)
    if not np.isfinite(g).any():
        return float(d[0])
    g = np.where(np.isfinite(g), g, -np.inf)
    k = int(np.argmax(g))
    best = _parabola_in_log(d, -g, k)
    return _on_grid(d[k] if best is None else best, sample_time_s)


def scan_with_refits(recording, rig, kept_fit, noise: dict, say=lambda message: None):
    """Refit at delays around ``kept_fit``'s (a fit with a transport delay) and return
    ``(best_fit, scan)``: the fit of lowest estimation residual sum of squares (``kept_fit`` itself
    when no other is lower) and the ``(delay_s, cost, seconds)`` of every fit tried, by delay.

    From the kept delay ``d`` the scan refits at ``d * 1.5`` and ``d / 1.5``, walks on by the same
    factor while the residual falls, then refits at the minimum of the parabola in ``log(delay)``
    through the best delay and its neighbours, then halves the wider side of the bracket until the
    neighbours are a grid step (a tenth of a sample) from the best; at most :data:`SCAN_REFITS` refits.  A refit that fails
    is left out of the scan."""
    dt = recording.sample_time_s
    d0 = next(e.values["delay_s"] for e in kept_fit.effects_ if e.name == "transport_delay")
    others = [e for e in kept_fit.effects_ if e.name != "transport_delay"]
    fits = {d0: (cand.estimation_cost(kept_fit, noise)[0], kept_fit, 0.0)}
    budget = [SCAN_REFITS]

    def at(delay_s):
        delay_s = _on_grid(delay_s, dt)
        if delay_s in fits or budget[0] <= 0:
            return delay_s
        budget[0] -= 1
        started = time.perf_counter()
        say(f"transport delay scan: refit at {delay_s * 1e3:.4g} ms")
        try:
            fit = cand.refit(recording, rig, others + [make_effect("transport_delay", delay_s=delay_s)], kept_fit)
            cost = cand.estimation_cost(fit, noise)[0]
        except Exception as exc:  # noqa: BLE001 - a delay that cannot be fitted is left out
            if not cand.is_solver_failure(exc):
                raise
            fit, cost = None, math.inf
        fits[delay_s] = (cost, fit, time.perf_counter() - started)
        return delay_s

    def costs():
        ds = sorted(d for d in fits if fits[d][1] is not None)
        return ds, [fits[d][0] for d in ds]

    at(d0 * SCAN_FACTOR)
    at(d0 / SCAN_FACTOR)
    while budget[0] > 1:
        ds, cs = costs()
        k = int(np.argmin(cs))
        if 0 < k < len(ds) - 1:
            break                                  # bracketed
        step = ds[k] * (SCAN_FACTOR if k == len(ds) - 1 else 1.0 / SCAN_FACTOR)
        if _on_grid(step, dt) in fits:
            break                                  # at the grid's lower end
        at(step)
    ds, cs = costs()
    k = int(np.argmin(cs))
    vertex = _parabola_in_log(ds, cs, k)
    if vertex is not None:
        at(vertex)
    # the residual's valley is sharper than a parabola over a factor of 1.5 (a 35 ms delay on the 10 ms
    # rig: 412921, 39001, 13172, 261288 at 21, 31, 33, 46 ms): halve the wider side of the bracket until
    # the grid's resolution (a tenth of a sample) or the budget ends it
    while budget[0] > 0:
        ds, cs = costs()
        k = int(np.argmin(cs))
        if not 0 < k < len(ds) - 1:
            break
        below, above = ds[k] - ds[k - 1], ds[k + 1] - ds[k]
        middle = _on_grid(0.5 * (ds[k] + (ds[k + 1] if above >= below else ds[k - 1])), dt)
        if middle in fits:
            break                                  # neighbours a grid step away
        at(middle)
    ds, cs = costs()
    k = int(np.argmin(cs))
    best_fit = fits[ds[k]][1]
    scan = [(d, fits[d][0], fits[d][2]) for d in sorted(fits)]
    std = _standard_error(ds, cs, k, cand.estimation_cost(best_fit, noise)[1])
    if hasattr(best_fit, "solver"):
        best_fit.solver["delay_scan"] = {"delay_s": [d for d, _, _ in scan], "cost": [c for _, c, _ in scan],
                                         "std_s": std}
    return best_fit, scan


def _standard_error(delays, costs, best: int, n_residuals: int) -> float | None:
    """The delay's standard error from the curvature of the estimation residual sum of squares (in noise
    units) at its minimum: ``C(d) ~ C0 + a (d - d0)^2`` gives ``sigma = sqrt(s^2 / a)``, ``s^2`` the
    residual variance in noise units (at least 1), as the Gauss-Newton covariance scales the others."""
    if not 0 < best < len(delays) - 1:
        return None
    a, _, _ = np.polyfit(np.asarray(delays[best - 1:best + 2], float), np.asarray(costs[best - 1:best + 2], float), 2)
    if not a > 0:
        return None
    curvature = math.sqrt(max(1.0, costs[best] / max(n_residuals, 1)) / a)
    # the scan's own resolution: the true minimum lies anywhere between the neighbours' midpoints
    resolution = (delays[best + 1] - delays[best - 1]) / 2.0 / math.sqrt(12.0)
    return float(max(curvature, resolution))
