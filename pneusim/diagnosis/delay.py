"""The transport delay: the one effect whose parameter has no gradient, estimated by scans.

A dead time moves the instants at which the valve sees each command; the model's response to it is a
step function of the delay between samples and has no useful derivative, so the fit keeps it fixed
(the effect's ``searched``) and the diagnosis scans it twice.  Everything the diagnosis does for a delay
alone is here:

1. **screening** -- a few fixed delays around the lag of the command-residual cross-correlation
   (:func:`screened_delays`), each screened by trust-region steps from the nominal optimum;
   :class:`ScreenedDelays` puts a parabola through the best gain and its neighbours
   (:func:`refine_from_screening`);
2. **refits** -- once a delay is kept and leads the findings, or comes close (:func:`delay_could_lead`),
   :func:`scan_with_refits` refits the whole model at delays around it (each warm-started from the kept
   fit) and walks downhill in the estimation residual sum of squares, then a parabola in ``log(delay)``
   through the best three, then halves the bracket.  Screening from the nominal fit's states favours the
   smaller delays (the states it starts from belong to no delay), so the kept delay is not the end.

Only the estimation part decides the delay; the validation part stays unseen.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..model import make_effect
from .budget import TimeBudgetExhausted
from .candidates import Candidate
from .refits import effect_parameters, estimation_cost
from .rules import (DELAY_GRID_PER_SAMPLE, DELAY_LAG_CORRELATION, DELAY_LAG_FACTORS, DELAY_SCAN_ERROR_RATIO,
                    MIN_DELAY_SAMPLES, SCAN_FACTOR, SCAN_REFITS, is_solver_failure)

__all__ = ["DELAY", "on_grid", "parabola_in_log", "scan_found_delay", "screened_delays", "ScreenedDelays", "refine_from_screening", "delay_could_lead",
           "scan_kept_delay", "scan_with_refits", "SCAN_FACTOR", "SCAN_REFITS"]

#: the effect estimated by scans (its delay is ``searched``: no gradient)
DELAY = "transport_delay"


def screened_delays(signatures: dict, sample_time_s: float) -> list | None:
    """The transport delays to screen: around the lag of the command-residual cross-correlation
    (:data:`~.rules.DELAY_LAG_FACTORS` times it, on the sample grid) where it points to one (a lag of at least
    a sample, a peak correlation above :data:`~.rules.DELAY_LAG_CORRELATION`), else None (the effect's own
    default scan)."""
    dt = sample_time_s
    lag = signatures.get("lag_s", float("nan"))
    if math.isfinite(lag) and lag >= dt and abs(signatures.get("lag_r", 0.0)) > DELAY_LAG_CORRELATION:
        return sorted({max(dt, round(f * lag / dt) * dt) for f in DELAY_LAG_FACTORS})
    return None


class ScreenedDelays:
    """The screening gains of the screened delays: ``add`` each candidate's gain (other effects are
    ignored), then ``refine`` the delay's variant to the best delay between them."""

    def __init__(self):
        self.scan = []

    def add(self, candidate: Candidate, gain: float) -> None:
        if candidate.name == DELAY:
            self.scan.append((candidate.effect.values["delay_s"], gain))

    def refine(self, variants: dict, sample_time_s: float) -> None:
        """Replace the delay's entry of ``variants`` (``{effect: (score, candidate, screening)}``) by the delay
        of :func:`refine_from_screening`, at the best variant's score."""
        if not (self.scan and DELAY in variants):
            return
        d_best = refine_from_screening(self.scan, sample_time_s)
        score, c, s = variants[DELAY]
        c = Candidate(DELAY, f"transport delay {d_best * 1e3:.3g} ms", make_effect(DELAY, delay_s=d_best), [])
        variants[DELAY] = (score, c, dict(s, parameters={"delay_s": d_best}))


def on_grid(delay_s: float, sample_time_s: float) -> float:
    """A delay rounded to the grid (:data:`~.rules.DELAY_GRID_PER_SAMPLE`), at least
    :data:`~.rules.MIN_DELAY_SAMPLES`."""
    return float(max(MIN_DELAY_SAMPLES * sample_time_s,
                     round(delay_s / sample_time_s * DELAY_GRID_PER_SAMPLE) / DELAY_GRID_PER_SAMPLE * sample_time_s))


def parabola_in_log(delays, values, best: int) -> float | None:
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
    best = parabola_in_log(d, -g, k)
    return on_grid(d[k] if best is None else best, sample_time_s)


def delay_could_lead(kept: list, refits: dict) -> bool:
    """Whether a kept transport delay is worth its refit scan: it leads the kept findings (``kept``, best
    validation fit first), or its validation error is at most :data:`~.rules.DELAY_SCAN_ERROR_RATIO` times
    the leader's.

    The scan moves the delay along its valley, so a delay short of the leader may still overtake it; but a
    look-alike that leaves several times the leader's error is not what the recording lacks, and its scan
    costs up to :data:`~.rules.SCAN_REFITS` whole refits (``docs/decisions/0033``)."""
    if DELAY not in kept:
        return False
    error = lambda k: 100.0 - refits[k][0].fit_percent  # noqa: E731
    return kept[0] == DELAY or error(DELAY) <= DELAY_SCAN_ERROR_RATIO * error(kept[0])


def scan_kept_delay(run) -> None:
    """Where :func:`delay_could_lead`, estimate the kept transport delay by :func:`scan_with_refits` (the kept
    one came from the screening's scan); the best delay replaces it when it still passes the keep test.
    ``run.refits`` and ``run.trials`` are updated in place."""
    if not delay_could_lead(run.kept_by_fit(), run.refits):
        return
    basis = run.baseline
    fit_d, c_d = run.refits[DELAY]
    best, scan = scan_with_refits(run, fit_d)
    trial = run.trials[DELAY]
    trial.seconds = (trial.seconds or 0.0) + sum(t for _, _, t in scan)
    trial.status += f"; delay scan with refits ({_scan_text(scan, best)}): "
    if best is fit_d:
        trial.status += "the kept delay is best"
        return
    cost_b, _ = estimation_cost(best, run.noise)
    ok, threshold, reason = run.stages.keep_test(basis.cost0, cost_b, basis.n_residuals, c_d.n_added, basis.fit0,
                                                 best.fit_percent, basis.floor)
    if not ok:
        trial.status += f"the best delay fails the test ({reason}); the kept delay stays"
        return
    trial.status += reason
    trial.fit_percent, trial.improvement_points = best.fit_percent, best.fit_percent - basis.fit0
    trial.estimation_cost_drop, trial.threshold = basis.cost0 - cost_b, threshold
    trial.parameters, _ = effect_parameters(best, DELAY)
    run.refits[DELAY] = (best, c_d)


def scan_found_delay(run, final):
    """Where a transport delay is among the effects of ``final`` (the findings' fit), estimate it by
    :func:`scan_with_refits` with the other findings present; returns the fit of the lowest estimation residual
    (``final`` itself where no other delay is lower), the delay's trial saying how the scan went.

    Why: a delay found jointly comes from the window's pre-fits, a factor of 1.5 apart and a parabola between them;
    the whole estimation part pins it to a tenth of a sample."""
    if DELAY not in {e.name for e in final.effects_}:
        return final
    best, scan = scan_with_refits(run, final)
    trial = run.trials.get(DELAY)
    if trial is not None:
        trial.seconds = (trial.seconds or 0.0) + sum(t for _, _, t in scan)
        trial.status += f"; delay scan with refits, the other findings present ({_scan_text(scan, best)})"
    return best


class _Scan:
    """The refits of one delay scan, by delay on the grid: ``fits[delay] = (cost, fit or None, seconds)``."""

    def __init__(self, run, kept_fit):
        self.run, self.kept_fit = run, kept_fit
        self.dt = run.recording.sample_time_s
        self.d0 = next(e.values["delay_s"] for e in kept_fit.effects_ if e.name == DELAY)
        self.others = [e for e in kept_fit.effects_ if e.name != DELAY]
        self.fits = {self.d0: (estimation_cost(kept_fit, run.noise)[0], kept_fit, 0.0)}
        self.budget = SCAN_REFITS
        #: why the scan ended before its refits did: a refit refused or stopped by the time budget (None: it did not)
        self.ended: str | None = None

    def at(self, delay_s: float) -> float:
        """Refit at ``delay_s`` (on the grid) unless done or out of budget; returns the delay on the grid."""
        delay_s = on_grid(delay_s, self.dt)
        if delay_s in self.fits or self.budget <= 0:
            return delay_s
        self.budget -= 1
        started = time.perf_counter()
        run = self.run
        run.say(f"transport delay scan: refit at {delay_s * 1e3:.4g} ms")
        try:
            fit = run.stages.refit(run.recording, run.rig, self.others + [make_effect(DELAY, delay_s=delay_s)],
                                   self.kept_fit)
            cost = estimation_cost(fit, run.noise)[0]
        except TimeBudgetExhausted as exc:
            # the budget is spent: the scan ends here (this refit listed as failed, with its seconds), not with
            # the refused ones after it listed as failed too
            self.budget, self.ended, fit, cost = 0, str(exc), None, math.inf
        except Exception as exc:  # noqa: BLE001 - a delay that cannot be fitted is left out
            if not is_solver_failure(exc):
                raise
            fit, cost = None, math.inf
        self.fits[delay_s] = (cost, fit, time.perf_counter() - started)
        return delay_s

    def costs(self):
        """``(delays, costs)`` of the fits that ran, by delay, and the index of the lowest cost."""
        ds = sorted(d for d in self.fits if self.fits[d][1] is not None)
        cs = [self.fits[d][0] for d in ds]
        return ds, cs, int(np.argmin(cs))


def scan_with_refits(run, kept_fit):
    """Refit at delays around ``kept_fit``'s (a fit with a transport delay) and return
    ``(best_fit, scan)``: the fit of lowest estimation residual sum of squares (``kept_fit`` itself
    when no other is lower) and the ``(delay_s, cost, seconds)`` of every fit tried, by delay.

    From the kept delay ``d`` the scan refits at ``d * 1.5`` and ``d / 1.5`` (:data:`~.rules.SCAN_FACTOR`),
    walks on by the same factor while the residual falls, then refits at the minimum of the parabola in
    ``log(delay)`` through the best delay and its neighbours, then halves the wider side of the bracket until
    the neighbours are a grid step (a tenth of a sample) from the best; at most :data:`~.rules.SCAN_REFITS`
    refits (``run.stages.refit``).  A refit that fails is left out of the scan; one that the time budget refuses
    or stops ends the scan with the refits it has (each later one would be refused too)."""
    s = _Scan(run, kept_fit)
    s.at(s.d0 * SCAN_FACTOR)
    s.at(s.d0 / SCAN_FACTOR)
    while s.budget > 1:
        ds, cs, k = s.costs()
        if 0 < k < len(ds) - 1:
            break                                  # bracketed
        step = ds[k] * (SCAN_FACTOR if k == len(ds) - 1 else 1.0 / SCAN_FACTOR)
        if on_grid(step, s.dt) in s.fits:
            break                                  # at the grid's lower end
        s.at(step)
    ds, cs, k = s.costs()
    vertex = parabola_in_log(ds, cs, k)
    if vertex is not None:
        s.at(vertex)
    # the residual's valley is sharper than a parabola over a factor of 1.5: halve the wider side of the
    # bracket until the grid's resolution (a tenth of a sample) or the budget ends it
    while s.budget > 0:
        ds, cs, k = s.costs()
        if not 0 < k < len(ds) - 1:
            break
        below, above = ds[k] - ds[k - 1], ds[k + 1] - ds[k]
        middle = on_grid(0.5 * (ds[k] + (ds[k + 1] if above >= below else ds[k - 1])), s.dt)
        if middle in s.fits:
            break                                  # neighbours a grid step away
        s.at(middle)
    ds, cs, k = s.costs()
    best_fit = s.fits[ds[k]][1]
    scan = [(d, s.fits[d][0], s.fits[d][2]) for d in sorted(s.fits)]
    std = _standard_error(ds, cs, k, estimation_cost(best_fit, run.noise)[1])
    if hasattr(best_fit, "solver"):
        best_fit.solver["delay_scan"] = {"delay_s": [d for d, _, _ in scan], "cost": [c for _, c, _ in scan],
                                         "std_s": std, "ended": s.ended}
    return best_fit, scan


def _scan_text(scan, best_fit) -> str:
    """The estimation residual by delay of ``scan`` (:func:`scan_with_refits`'s), and where the time budget ended
    it before its refits did, why (``best_fit``: its result)."""
    ended = (getattr(best_fit, "solver", None) or {}).get("delay_scan", {}).get("ended")
    return ("estimation residual by delay: " + ", ".join(f"{d * 1e3:.4g} ms {c:.0f}" for d, c, _ in scan)
            + (f"; the scan ended there, {ended}" if ended else ""))


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
