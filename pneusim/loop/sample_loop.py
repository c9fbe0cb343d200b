"""The sample loop of the mixed-reality environment, paced or as fast as possible.

At every sample ``k`` the loop, in this order:

1. waits for the deadline of sample ``k`` (:mod:`pneusim.mre.clock`; no wait in fast mode);
2. **measures**: ``plant.measure()``;
3. **identifies**: each online estimator predicts ``yhat(k | k-h)`` and takes ``y(k)``;
4. **controls**: the controller turns reference and measured position into ``u(k)``;
5. **actuates**: ``plant.step(u(k))`` (the command is held for one sample);
6. completes the estimators' bookkeeping with ``u(k)`` and writes the row.

The same components run in fast and in real-time mode, so a run rehearsed
offline (``--fast``) gives the same recording as the live one (``--realtime``),
timing columns aside.  Per sample the loop keeps the lateness of the start
against its absolute deadline, the latency from the start of the measurement to
the command being ready, and the loop's own computation time; a sample whose
work ends after the next deadline is an *overrun*.  A late sample runs at once
(the deadlines never move, so the loop catches up without drift); no sample is
skipped, so on a real plant a late sample is measured after its nominal time, by
the ``lateness_s`` the recording holds.

On Ctrl-C (:class:`KeyboardInterrupt`), on any exception raised by a
component (a *fault*) or when the overruns exceed their budget, the loop stops,
the plant's valve is sent to its null (``plant.safe_stop``), the writer is
flushed and closed, and :class:`LoopResult` holds everything taken so far.
"""

from __future__ import annotations

import gc
import math
import sys
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from .clock import FastPacing, Pacing

__all__ = ["run_loop", "LoopResult", "StatusLine", "timing_summary", "row_columns"]

STOP_COMPLETED = "completed"
STOP_INTERRUPTED = "interrupted (Ctrl-C)"
STOP_FAULT = "fault"
STOP_OVERRUNS = "overrun budget exceeded"


@dataclass
class LoopResult:
    """Everything a loop run produced; arrays have one entry per recorded sample (``n_samples``).

    Attributes
    ----------
    position_m, valve_cmd_V, reference, pressure_a_Pa, pressure_b_Pa : ndarray (N,)
        Measured position [m], applied command [V], reference (m closed loop, V open loop),
        measured chamber pressures [Pa] (NaN when the plant has none).
    plant_flag : ndarray (N,) of int
        0: a fresh measurement; 1: the plant could not deliver one and the last was held.
    predictions : {(estimator, h): ndarray (N,)}
        ``yhat(k | k-h)`` in the estimators' output unit.
    thetas : {estimator: ndarray (N, 2n)}
        ``theta`` after each sample.
    lateness_s, latency_s, compute_s : ndarray (N,)
        Start of the sample minus its deadline (NaN in fast mode), measurement start to command
        ready, and the whole sample's computation, s.
    overruns, late_half : int
        Samples whose work ended after the next deadline; samples started more than half a
        sample late.
    stop_reason : str
        ``completed``, ``interrupted (Ctrl-C)``, ``fault`` or ``overrun budget exceeded``.
    error : str or None
        The fault's message.
    """

    sample_time_s: float
    n_planned: int
    pacing: str
    position_m: np.ndarray
    valve_cmd_V: np.ndarray
    reference: np.ndarray
    pressure_a_Pa: np.ndarray
    pressure_b_Pa: np.ndarray
    plant_flag: np.ndarray
    predictions: dict = field(default_factory=dict)
    thetas: dict = field(default_factory=dict)
    lateness_s: np.ndarray | None = None
    latency_s: np.ndarray | None = None
    compute_s: np.ndarray | None = None
    overruns: int = 0
    late_half: int = 0
    stop_reason: str = STOP_COMPLETED
    error: str | None = None
    wall_time_s: float = 0.0
    valve_to_null: bool = False
    #: the exception of a fault (re-raised by callers that do not handle faults themselves)
    exception: BaseException | None = field(default=None, repr=False)

    @property
    def n_samples(self) -> int:
        return int(self.position_m.shape[0])

    @property
    def completed(self) -> bool:
        return self.stop_reason == STOP_COMPLETED


class StatusLine:
    """A live one-line status on a terminal stream (samples, overruns, lateness, one-step error).

    Parameters
    ----------
    stream : file
        Where to write (``sys.stderr`` by default).
    interval_s : float
        Wall time between two updates.
    label : str
        First word of the line.
    """

    def __init__(self, stream=None, interval_s: float = 0.5, label: str = "mre"):
        self.stream = stream if stream is not None else sys.stderr
        self.label = label
        self.interval_s = float(interval_s)
        self.last_text = ""

    def show(self, k: int, n: int, overruns: int, late_half: int, lateness_s: np.ndarray,
             err: float, err_name: str) -> None:
        lat = lateness_s[np.isfinite(lateness_s)]
        timing = (f", lateness p50 {np.percentile(lat, 50) * 1e3:.3f} ms p99 {np.percentile(lat, 99) * 1e3:.3f} ms "
                  f"max {lat.max() * 1e3:.3f} ms" if lat.size else "")
        e = f", 1-step error ({err_name}) {err:+.4g}" if err_name else ""
        paced = f", overruns {overruns}, late > Ts/2 {late_half}{timing}" if lat.size else ""   # none when fast
        self.last_text = f"{self.label}: {k}/{n} samples ({100.0 * k / max(n, 1):.0f} %){paced}{e}"
        self.stream.write("\r" + self.last_text + "   ")
        self.stream.flush()

    def close(self) -> None:
        if self.last_text:
            self.stream.write("\n")
            self.stream.flush()


def run_loop(plant, reference: np.ndarray, controller, estimators: Mapping[str, object],
             to_output: Callable[[float], float], to_input: Callable[[float, int], float], *,
             pacing: Pacing | None = None, n_warm: int = 0, writer=None,
             status: StatusLine | None = None, overrun_budget: int | None = None, null_V: float | None = None,
             stop_after: int | None = None) -> LoopResult:
    """Run the loop over ``reference`` after ``n_warm`` warm-up samples; the plant must be reset.

    Parameters
    ----------
    plant : Plant
        Already reset at sample ``-n_warm``.
    reference : ndarray (N,)
        Position reference in m (``controller`` given) or the valve command in V (open loop).
    controller : Controller or None
    estimators : {name: PaperRLS-like}
        ``update(y) -> {h: yhat}``, ``add_input(u)``, ``theta``, ``horizons``.
    to_output, to_input : callable
        Position (m) to the estimators' output; command (V) and sample index to their input.
    pacing : Pacing
        :class:`~pneusim.mre.clock.FastPacing` (default), real-time or sleep pacing.
    writer : RecordingWriter or None
        Receives one row per recorded sample (see :func:`row_columns`); in a paced run its ``idle``
        (formatting the rows) is the pacer's :attr:`~pneusim.mre.clock.Pacing.idle`, i.e. done in
        the wait for the next deadline, not counted in ``compute_s``.
    status : StatusLine or None
    overrun_budget : int or None
        Stop (valve to null) once more samples than this have overrun.
    null_V : float or None
        Valve null sent by ``plant.safe_stop`` when the loop ends.
    stop_after : int or None
        Raise a fault after this many recorded samples (used to test the fault path).
    """
    pacing = pacing or FastPacing(plant.sample_time_s)
    ts = pacing.sample_time_s
    n = int(reference.shape[0])
    closed = controller is not None
    # per-sample values go to Python lists (an append costs a third of a numpy item assignment);
    # the arrays are made once at the end; thetas go straight into their (n, 2n) arrays
    pos, cmd, pa, pb, flag = [], [], [], [], []
    late, latency, compute = [], [], []
    preds = {(name, h): [] for name, est in estimators.items() for h in est.horizons}
    thetas = {name: np.full((n, est.theta.size), np.nan) for name, est in estimators.items()}
    first_h1 = next(((name, 1) for name, est in estimators.items() if 1 in est.horizons), None)
    plan = [_estimator_plan(name, est, preds, thetas[name]) for name, est in estimators.items()]
    realtime = pacing.realtime
    clock = time.perf_counter
    half_ts = 0.5 * ts
    nan = float("nan")
    overruns = late_half = 0
    done = 0
    stop, error, exception = STOP_COMPLETED, None, None
    gc_was_enabled = gc.isenabled()
    if realtime:
        gc.collect()
        gc.disable()
    next_status = 0.0
    win_start = 0
    idle_before = pacing.idle
    if realtime and writer is not None and hasattr(writer, "idle"):
        pacing.idle = writer.idle         # rows are formatted in the wait for the next deadline
    started = pacing.start()
    try:
        for j in range(n_warm + n):
            k = j - n_warm
            deadline = pacing.wait(j)
            t0 = clock()
            m = plant.measure()
            ref = float(reference[k if k > 0 else 0])
            if k >= 0:
                y = to_output(m.position_m)
                row_preds = []
                for update, columns, _add, _log in plan:
                    values = update(y)
                    for col, v in zip(columns, values):
                        col.append(v)
                    row_preds += values
            u = controller.command(m.t_s, ref, m.position_m) if closed else ref
            t_cmd = clock()
            if k < n - 1:
                plant.step(u)
            if k >= 0:
                u_est = to_input(u, k)
                for _update, _columns, add_input, log_theta in plan:
                    add_input(u_est)
                    log_theta(k)
                u = float(u)
                fl = getattr(plant, "measurement_flag", 0)
                lat = t_cmd - t0
                pos.append(m.position_m)
                cmd.append(u)
                pa.append(m.pressure_a_Pa)
                pb.append(m.pressure_b_Pa)
                flag.append(fl)
                latency.append(lat)
                if realtime:
                    lt = t0 - deadline
                    if lt > half_ts:
                        late_half += 1
                else:
                    lt = nan
                late.append(lt)
                if writer is not None:
                    row = [k * ts, ref, u] if closed else [k * ts, u]
                    row += [m.position_m, m.pressure_a_Pa, m.pressure_b_Pa, lt, lat, float(fl)]
                    writer.append(row + row_preds)
                done = k + 1
                t_end = clock()
                compute.append(t_end - t0)
                if realtime and t_end > deadline + ts:
                    overruns += 1
                    if overrun_budget is not None and overruns > overrun_budget:
                        stop = STOP_OVERRUNS
                        error = f"{overruns} samples overran (budget {overrun_budget})"
                        break
                if status is not None and t_end >= next_status:
                    err = nan
                    if first_h1 is not None:
                        err = to_output(m.position_m) - preds[first_h1][k]
                    status.show(done, n, overruns, late_half, np.array(late[win_start:done], dtype=float), err,
                                first_h1[0] if first_h1 else "")
                    win_start = done
                    next_status = t_end + status.interval_s
                if stop_after is not None and done >= stop_after:
                    raise RuntimeError(f"fault injected after {done} samples")
    except KeyboardInterrupt:
        stop = STOP_INTERRUPTED
    except Exception as exc:  # a component's fault: stop safely, keep what was taken, report it
        stop, exception = STOP_FAULT, exc
        error = str(exc) if _is_user_error(exc) else f"{type(exc).__name__}: {exc}"
    finally:
        pacing.idle = idle_before
        if gc_was_enabled:
            gc.enable()
        wall = clock() - started
        null_sent = False
        safe = getattr(plant, "safe_stop", None)
        if safe is not None:
            try:
                safe(null_V)
                null_sent = True
            except Exception as exc:   # the plant may be the fault; say so, do not hide the first fault
                error = (error + "; " if error else "") + f"valve to null failed: {exc}"
        if writer is not None:
            writer.close()
        if status is not None:
            status.close()

    def arr(values, dtype=float):
        return np.array(values[:done], dtype=dtype)

    return LoopResult(ts, n, pacing.name, arr(pos), arr(cmd), np.asarray(reference[:done], float).copy(),
                      arr(pa), arr(pb), arr(flag, int),
                      {key: arr(v) for key, v in preds.items()},
                      {key: v[:done].copy() for key, v in thetas.items()},
                      arr(late), arr(latency), arr(compute), overruns, late_half, stop, error,
                      wall, null_sent, exception)


def _estimator_plan(name, est, preds, theta_log):
    """``(update, prediction lists, add_input, log_theta)`` of one estimator, bound once before the loop.

    ``update(y)`` returns the predictions in the order of ``est.horizons``; ``log_theta(k)`` writes
    ``theta`` into row ``k`` of ``theta_log``, without allocating for estimators with ``theta_logger``
    (:class:`~pneusim.scenario.online.PaperRLS`), through ``est.theta`` for any other.
    """
    unique = tuple(dict.fromkeys(est.horizons))         # a horizon given twice has one column

    def values(y, _update=est.update):
        d = _update(y)
        return [d[h] for h in unique]
    logger = getattr(est, "theta_logger", None)
    if logger is not None:
        log_theta = logger(theta_log)
    else:
        def log_theta(k):
            theta_log[k] = est.theta
    return values, [preds[(name, h)] for h in unique], est.add_input, log_theta


def _is_user_error(exc: Exception) -> bool:
    from ..errors import PneusimError
    return isinstance(exc, PneusimError)


def row_columns(closed: bool, prediction_names) -> list[str]:
    """Header of the rows :func:`run_loop` writes: the recording's signals, the timing, the predictions."""
    return (["time_s"] + (["reference_m"] if closed else []) + ["valve_cmd_V", "position_m", "pressure_a_Pa",
            "pressure_b_Pa", "lateness_s", "latency_s", "plant_flag"] + list(prediction_names))


def timing_summary(result: LoopResult) -> dict:
    """Lateness p50/p99/max, overruns and computation per sample of a run, in s and counts."""
    ts, n = result.sample_time_s, result.n_samples
    out = {"samples": n, "pacing": result.pacing, "sample_time_s": ts, "overruns": result.overruns,
           "late_half_sample": result.late_half,
           "late_half_sample_percent": 100.0 * result.late_half / n if n else math.nan}
    for name, arr in (("lateness_s", result.lateness_s), ("latency_s", result.latency_s),
                      ("compute_s", result.compute_s)):
        a = arr[np.isfinite(arr)] if arr is not None else np.empty(0)
        out[name] = ({"p50": float(np.percentile(a, 50)), "p99": float(np.percentile(a, 99)),
                      "max": float(a.max()), "mean": float(a.mean())} if a.size else None)
    return out
