"""The sample loop shared by the mixed-reality environment and the scenarios' online runs, paced or as
fast as possible.

At every sample ``k`` the loop, in this order:

1. waits for the deadline of sample ``k`` (:mod:`pneusim.loop.pacing`; no wait in fast mode);
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

A position reading or a command that is not a finite number (a sensor fault, a controller fed one) is a
fault too: it never reaches the valve.

On Ctrl-C (:class:`KeyboardInterrupt`), on SIGTERM (:class:`pneusim.shutdown.Terminated`, where the
caller turned it into an exception with :func:`pneusim.shutdown.sigterm_raises`), on any exception raised by a
component (a *fault*) or when the overruns exceed their budget, the loop stops,
the plant's valve is sent to its null (``plant.safe_stop``), the writer is
flushed and closed, and :class:`LoopResult` holds everything taken so far.
"""

from __future__ import annotations

import gc
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from ..errors import PneusimError
from ..shutdown import Terminated
from .pacing import FastPacing, Pacing
from .status import StatusLine

__all__ = ["run_loop", "LoopResult", "row_columns", "STOP_COMPLETED", "STOP_INTERRUPTED", "STOP_TERMINATED",
           "STOP_FAULT", "STOP_OVERRUNS"]

STOP_COMPLETED = "completed"
STOP_INTERRUPTED = "interrupted (Ctrl-C)"
STOP_TERMINATED = "terminated (SIGTERM)"
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
        ``completed``, ``interrupted (Ctrl-C)``, ``terminated (SIGTERM)``, ``fault`` or ``overrun budget
        exceeded``.
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
    #: the exception of a fault, or the Ctrl-C / SIGTERM that stopped the loop (re-raised by callers that do
    #: not handle them themselves)
    exception: BaseException | None = field(default=None, repr=False)

    @property
    def n_samples(self) -> int:
        return int(self.position_m.shape[0])

    @property
    def completed(self) -> bool:
        return self.stop_reason == STOP_COMPLETED


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
        :class:`~pneusim.loop.pacing.FastPacing` (default), real-time or sleep pacing.
    writer : RecordingWriter or None
        Receives one row per recorded sample (see :func:`row_columns`); in a paced run its ``idle``
        (formatting the rows) is the pacer's :attr:`~pneusim.loop.pacing.Pacing.idle`, i.e. done in
        the wait for the next deadline, not counted in ``compute_s``.
    status : StatusLine or None
    overrun_budget : int or None
        Stop (valve to null) once more samples than this have overrun.
    null_V : float or None
        Valve null sent by ``plant.safe_stop`` when the loop ends.
    stop_after : int or None
        Raise a fault after this many recorded samples (tests of the stop path).
    """
    pacing = pacing or FastPacing(plant.sample_time_s)
    loop = _SampleLoop(plant, reference, controller, estimators, to_output, to_input, pacing, writer, status,
                       overrun_budget, stop_after)
    stop, error, exception = STOP_COMPLETED, None, None
    with _quiet_process(pacing, writer):
        started = pacing.start()
        try:
            for j in range(n_warm + loop.n):
                loop.sample(j - n_warm, pacing.wait(j))
        except _OverrunBudgetExceeded as exc:
            stop, error = STOP_OVERRUNS, str(exc)
        except KeyboardInterrupt as exc:
            stop, exception = (STOP_TERMINATED if isinstance(exc, Terminated) else STOP_INTERRUPTED), exc
        except Exception as exc:  # a component's fault: stop safely, keep what was taken, report it
            stop, exception = STOP_FAULT, exc
            error = str(exc) if isinstance(exc, PneusimError) else f"{type(exc).__name__}: {exc}"
        finally:
            wall = pacing.clock() - started
            null_sent, error = _valve_to_null(plant, null_V, error)
            if writer is not None:
                writer.close()
            if status is not None:
                status.close(loop.done)
    return loop.result(stop, error, exception, wall, null_sent)


class _OverrunBudgetExceeded(Exception):
    """More samples overran than the budget allows (the loop stops; not a fault)."""


class _quiet_process:
    """While a paced loop runs: no garbage collection, and the writer's formatting in the pacer's idle time."""

    def __init__(self, pacing: Pacing, writer):
        self.pacing, self.writer = pacing, writer

    def __enter__(self):
        self.idle_before = self.pacing.idle
        self.gc_was_enabled = gc.isenabled()
        if self.pacing.realtime:
            gc.collect()
            gc.disable()
            if self.writer is not None and hasattr(self.writer, "idle"):
                self.pacing.idle = self.writer.idle   # rows are formatted in the wait for the next deadline
        return self

    def __exit__(self, *exc):
        self.pacing.idle = self.idle_before
        if self.gc_was_enabled:
            gc.enable()
        return False


def _valve_to_null(plant, null_V, error):
    """``plant.safe_stop(null_V)`` where the plant has one; ``(sent, error)`` with a failure added to the error
    (the plant may be the fault: say so, do not hide the first fault)."""
    safe = getattr(plant, "safe_stop", None)
    if safe is None:
        return False, error
    try:
        safe(null_V)
    except Exception as exc:  # noqa: BLE001 - reported, the run's result is kept
        return False, (error + "; " if error else "") + f"valve to null failed: {exc}"
    return True, error


class _SampleLoop:
    """One run's components and what it has taken so far; :meth:`sample` is one sample of the loop.

    Per-sample values go to Python lists (an append costs a third of a numpy item assignment); the
    arrays are made once at the end; thetas go straight into their (n, 2n) arrays.
    """

    def __init__(self, plant, reference, controller, estimators, to_output, to_input, pacing, writer, status,
                 overrun_budget, stop_after):
        self.plant, self.reference, self.controller = plant, reference, controller
        self.to_output, self.to_input = to_output, to_input
        self.pacing, self.writer, self.status = pacing, writer, status
        self.overrun_budget, self.stop_after = overrun_budget, stop_after
        self.n = n = int(reference.shape[0])
        self.ts = pacing.sample_time_s
        self.clock = pacing.clock
        self.realtime = pacing.realtime
        self.closed = controller is not None
        self.pos, self.cmd, self.pa, self.pb, self.flag = [], [], [], [], []
        self.late, self.latency, self.compute = [], [], []
        self.preds = {(name, h): [] for name, est in estimators.items() for h in est.horizons}
        self.thetas = {name: np.full((n, est.theta.size), np.nan) for name, est in estimators.items()}
        self.first_h1 = next(((name, 1) for name, est in estimators.items() if 1 in est.horizons), None)
        self.plan = [_estimator_plan(name, est, self.preds, self.thetas[name]) for name, est in estimators.items()]
        self.overruns = self.late_half = self.done = 0
        self.next_status = 0.0
        self.win_start = 0

    def sample(self, k: int, deadline: float) -> None:
        """Sample ``k`` (negative: warm-up, nothing recorded): measure, identify, control, actuate, record."""
        t0 = self.clock()
        m = self.plant.measure()
        x = m.position_m
        if x - x != 0.0:          # NaN or infinite: no controller may act on it (x - x is 0 for every finite x)
            raise PneusimError(f"sample {k}: the position reading {x!r} is not a finite number (a sensor fault); "
                               "the loop stops with the valve at its null")
        ref = float(self.reference[k if k > 0 else 0])
        row_preds = self.identify(x) if k >= 0 else None
        u = self.controller.command(m.t_s, ref, x) if self.closed else ref
        if u - u != 0.0:
            raise PneusimError(f"sample {k}: the command {u!r} is not a finite number; it is not sent, the loop "
                               "stops with the valve at its null")
        t_cmd = self.clock()
        if k < self.n - 1:
            self.plant.step(u)
        if k >= 0:
            self.learn_input(k, u)
            self.record(k, m, ref, float(u), row_preds, t0, t_cmd, deadline)
            self.check_timing(k, m, t0, deadline)

    def identify(self, position_m: float) -> list:
        """Each estimator predicts and takes ``y(k)``; returns the row's predictions in column order."""
        y = self.to_output(position_m)
        row_preds = []
        for update, columns, _add, _log in self.plan:
            values = update(y)
            for col, v in zip(columns, values):
                col.append(v)
            row_preds += values
        return row_preds

    def learn_input(self, k: int, u) -> None:
        """Each estimator takes the applied ``u(k)`` and logs its ``theta``."""
        u_est = self.to_input(u, k)
        for _update, _columns, add_input, log_theta in self.plan:
            add_input(u_est)
            log_theta(k)

    def record(self, k: int, m, ref: float, u: float, row_preds: list, t0: float, t_cmd: float,
               deadline: float) -> None:
        """Keep the sample (measurement, command, lateness, latency) and write its row."""
        fl = getattr(self.plant, "measurement_flag", 0)
        lat = t_cmd - t0
        self.pos.append(m.position_m)
        self.cmd.append(u)
        self.pa.append(m.pressure_a_Pa)
        self.pb.append(m.pressure_b_Pa)
        self.flag.append(fl)
        self.latency.append(lat)
        if self.realtime:
            lt = t0 - deadline
            if lt > 0.5 * self.ts:
                self.late_half += 1
        else:
            lt = float("nan")
        self.late.append(lt)
        if self.writer is not None:
            row = [k * self.ts, ref, u] if self.closed else [k * self.ts, u]
            row += [m.position_m, m.pressure_a_Pa, m.pressure_b_Pa, lt, lat, float(fl)]
            self.writer.append(row + row_preds)
        self.done = k + 1

    def check_timing(self, k: int, m, t0: float, deadline: float) -> None:
        """The sample's computation time; count an overrun (stop past the budget), show the status, inject
        the test fault."""
        t_end = self.clock()
        self.compute.append(t_end - t0)
        if self.realtime and t_end > deadline + self.ts:
            self.overruns += 1
            if self.overrun_budget is not None and self.overruns > self.overrun_budget:
                raise _OverrunBudgetExceeded(f"{self.overruns} samples overran (budget {self.overrun_budget})")
        if self.status is not None and t_end >= self.next_status:
            self.show_status(k, m)
            self.next_status = t_end + self.status.interval_s
        if self.stop_after is not None and self.done >= self.stop_after:
            raise RuntimeError(f"fault injected after {self.done} samples")

    def show_status(self, k: int, m) -> None:
        err = float("nan")
        if self.first_h1 is not None:
            err = self.to_output(m.position_m) - self.preds[self.first_h1][k]
        self.status.show(self.done, self.n, self.overruns, self.late_half,
                         np.array(self.late[self.win_start:self.done], dtype=float), err,
                         self.first_h1[0] if self.first_h1 else "")
        self.win_start = self.done

    def result(self, stop: str, error, exception, wall: float, null_sent: bool) -> LoopResult:
        done = self.done

        def arr(values, dtype=float):
            return np.array(values[:done], dtype=dtype)

        return LoopResult(self.ts, self.n, self.pacing.name, arr(self.pos), arr(self.cmd),
                          np.asarray(self.reference[:done], float).copy(), arr(self.pa), arr(self.pb),
                          arr(self.flag, int), {key: arr(v) for key, v in self.preds.items()},
                          {key: v[:done].copy() for key, v in self.thetas.items()},
                          arr(self.late), arr(self.latency), arr(self.compute), self.overruns, self.late_half,
                          stop, error, wall, null_sent, exception)


def _estimator_plan(name, est, preds, theta_log):
    """``(update, prediction lists, add_input, log_theta)`` of one estimator, bound once before the loop.

    ``update(y)`` returns the predictions in the order of ``est.horizons``; ``log_theta(k)`` writes
    ``theta`` into row ``k`` of ``theta_log``, without allocating for estimators with ``theta_logger``
    (:class:`~pneusim.online.PaperRLS`), through ``est.theta`` for any other.
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


def row_columns(closed: bool, prediction_names) -> list[str]:
    """Header of the rows :func:`run_loop` writes: the recording's signals, the timing, the predictions."""
    return (["time_s"] + (["reference_m"] if closed else []) + ["valve_cmd_V", "position_m", "pressure_a_Pa",
            "pressure_b_Pa", "lateness_s", "latency_s", "plant_flag"] + list(prediction_names))
