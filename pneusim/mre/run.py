"""Run an MRE file: build the components, pick the plant and the pacing, record, report.

:func:`run_mre` is what ``pneusim mre`` calls.  Its output folder holds

* ``recording.csv``: the run as a ``pneusim-recording/1`` file, written row by
  row while the loop runs (plus the extra columns ``lateness_s``, ``latency_s``,
  ``plant_flag`` and every prediction ``yhat_*``);
* ``coefficients.npz``: ``theta`` of every estimator after every sample, and the per-sample timing;
* ``summary.json``: how the run ended, timing statistics, plant counters, identified models;
* the report, ``index.html`` (self-contained) and ``report.md``, and its figures (:mod:`pneusim.mre.report`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import PneusimError
from ..loop import LoopResult, StatusLine, make_pacing, row_columns, run_loop, timing_summary
from ..metrics import error_stats
from ..outputs import atomic_path, write_json_atomic
from ..plant import SimulatedPlant
from ..plausibility import check_plausible
from ..recording import MIN_SAMPLES, read_recording
from ..version import __version__
from .daq import DaqPlant
from .plants import ReplayPlant, parse_plant
from .recorder import RecordingWriter
from .report import write_report
from .rt import RealtimeScope, RealtimeSettings
from .scenario import Components, build_components
from .udp import UdpPlant

__all__ = ["run_mre", "MreRun", "make_plant", "prediction_column"]


@dataclass
class MreRun:
    """What :func:`run_mre` returns: the loop result, the summary written to ``summary.json``, the files."""

    result: LoopResult
    summary: dict
    out_dir: Path
    recording_path: Path


def slug(name: str) -> str:
    """``'RLS ARMA order 4'`` -> ``'rls_arma_order_4'``."""
    return re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_") or "estimator"


def prediction_column(name: str, h: int, unit: str) -> str:
    """CSV column of the ``h``-step prediction of estimator ``name``, e.g. ``yhat_rls_arma_order_4_h1_cm``."""
    return f"yhat_{slug(name)}_h{h}_{unit}"


def make_plant(choice, rig, effects, *, seed: int, noise_scale: float, mode: str, udp_reply_timeout_s=None,
               daq_modules=None):
    """The plant of a parsed ``--plant`` choice."""
    if choice.kind == "sim":
        return SimulatedPlant(rig, effects, seed=seed, noise_scale=noise_scale)
    if choice.kind == "replay":
        rec = read_recording(choice.path)
        if not math.isclose(rec.sample_time_s, rig.sample_time_s, rel_tol=1e-9):
            made = f" (rig {rec.rig})" if rec.rig else ""
            raise PneusimError(f"--plant replay:{choice.path}: the recording{made} was sampled every "
                               f"{rec.sample_time_s:g} s, the MRE file's rig {rig.name} every {rig.sample_time_s:g} s; "
                               f"replay a recording of {rig.name} (e.g. pneusim simulate --rig {rig.name} --input "
                               f"steps --loop open --out {rig.name}-run.csv) or use an MRE file of its rig")
        return ReplayPlant(rec)
    if choice.kind == "udp":
        timeout = udp_reply_timeout_s
        if timeout is None:
            timeout = 0.5 * rig.sample_time_s if mode == "realtime" else 1.0
        return UdpPlant(choice.host, choice.port, rig.sample_time_s, reply_timeout_s=timeout)
    return DaqPlant(rig, daq_modules)


def run_mre(spec: dict, out_dir, *, plant: str | None = None, mode: str | None = None,
            duration_s: float | None = None, status: bool = False, report: bool = True,
            plant_object=None, stop_after: int | None = None, pacing=None, rt=None) -> MreRun:
    """Run a checked MRE dict (:func:`pneusim.mre.scenario.load_mre`) and write its folder.

    Parameters
    ----------
    plant : str or None
        ``sim``, ``replay:FILE``, ``udp:HOST:PORT`` or ``nidaqmx`` (default: the file's ``mre.plant``).
    mode : {'fast', 'realtime'} or None
        Default: the file's ``mre.mode``.
    duration_s : float or None
        Default: the file's ``mre.duration_s``.
    plant_object : Plant or None
        A ready plant (tests); overrides ``plant``.
    stop_after : int or None
        Inject a fault after this many samples (tests of the stop path).
    pacing : Pacing or None
        Overrides the pacing of ``mode`` (the benchmark's plain-sleep pacing).
    rt : RealtimeSettings or None
        Operating-system settings while a paced loop runs (:mod:`pneusim.mre.rt`; default
        :class:`~pneusim.mre.rt.RealtimeSettings()`: SCHED_FIFO, locked memory, 1 ns timer slack;
        ``RealtimeSettings.off()`` for none).  Not used in fast mode.  What took effect and what the
        system refused are in ``summary['realtime_os']``.
    """
    m = spec["mre"]
    mode = mode or m["mode"]
    choice = parse_plant(plant or m["plant"])
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    comp = build_components(spec, duration_s)
    pl = plant_object if plant_object is not None else make_plant(
        choice, comp.rig, comp.effects, seed=int(m["seed"]), noise_scale=float(m["noise_scale"]), mode=mode,
        udp_reply_timeout_s=m["udp_reply_timeout_s"])
    _check_replay_length(pl, choice, comp)
    pred_keys, pred_cols = _prediction_columns(comp)
    meta = _recording_metadata(spec, comp, mode, choice.text if plant_object is None else type(pl).__name__, pl)
    rec_path = out / "recording.csv"
    pacing = pacing or make_pacing(mode, comp.rig.sample_time_s)
    scope = RealtimeScope(rt if rt is not None else RealtimeSettings()) if pacing.realtime else RealtimeScope(None)
    res = _run_recorded(pl, comp, m, pacing, scope, rec_path, meta, row_columns(comp.controller is not None, pred_cols),
                        status, stop_after)
    summary = _summary(spec, res, comp, choice, pl, mode, rec_path, pred_keys, pred_cols)
    summary["recording_check"] = recording_check(rec_path, comp.rig) if res.n_samples >= MIN_SAMPLES else None
    summary["realtime_os"] = {"applied": scope.describe() if pacing.realtime else "none (fast mode)",
                              "notices": list(scope.notices)}
    _write_results(out, res, summary)
    run = MreRun(res, summary, out, rec_path)
    if report and res.n_samples >= 2:
        write_report(run, comp, spec)
    return run


def recording_check(path: Path, rig) -> str | None:
    """What ``pneusim check`` would say against the run's recording (None: valid and plausible for ``rig``):
    a run must not end as if all were well with a recording its own check refuses (too much sensor noise,
    a sensor fault on a real rig)."""
    try:
        check_plausible(read_recording(path), rig)
    except PneusimError as exc:
        return str(exc)
    return None


def _check_replay_length(plant, choice, comp: Components) -> None:
    """A replayed recording must hold the whole run, warm-up included."""
    n = comp.reference.shape[0]
    if isinstance(plant, ReplayPlant) and plant.remaining < n + comp.n_warm:
        raise PneusimError(f"--plant {choice.text}: the recording holds {plant.remaining} samples, the run needs "
                           f"{n + comp.n_warm} (warm-up included); shorten --duration or mre.warmup_s")


def _prediction_columns(comp: Components) -> tuple[list, list]:
    """``([(estimator, h)], [CSV column])`` of every prediction, columns unique."""
    pred_keys = [(name, h) for name, est in comp.estimators.items() for h in est.horizons]
    pred_cols = [prediction_column(name, h, comp.output_unit) for name, h in pred_keys]
    if len(set(pred_cols)) != len(pred_cols):
        raise PneusimError("two identifiers give the same prediction column name; rename one")
    return pred_keys, pred_cols


def _recording_metadata(spec: dict, comp: Components, mode: str, plant_text: str, plant) -> dict:
    """The recording's metadata: format, rig, loop, the run's plant and mode, the controller."""
    m = spec["mre"]
    closed = comp.controller is not None
    meta = {"format": "pneusim-recording/1", "sample_time_s": repr(comp.rig.sample_time_s), "rig": comp.rig.name,
            "loop": "closed" if closed else "open",
            "description": m["title"] or m["name"],
            "generator": f"pneusim {__version__} mre", "seed": str(m["seed"]),
            "effects": ";".join(repr(e) for e in comp.effects) or "none",
            "mre_plant": plant_text, "mre_mode": mode, "mre_output_unit": comp.output_unit}
    if getattr(plant, "open_loop", False):
        meta["mre_plant_note"] = ("open loop: the measurements are played back from the recording; "
                                  "the loop's commands do not act on them")
    if closed:
        meta.update(comp.controller.metadata())
    return meta


def _run_recorded(plant, comp: Components, m: dict, pacing, scope, rec_path: Path, meta: dict, columns: list,
                  status: bool, stop_after: int | None) -> LoopResult:
    """Reset the plant and run the loop inside the real-time ``scope``, its rows written to ``rec_path`` as it
    runs; the writer and the plant are closed however it ends."""
    ts = comp.rig.sample_time_s
    budget = int(math.floor(float(m["overrun_budget"]) * comp.reference.shape[0])) if pacing.realtime else None
    null_V = float(comp.rig.params["valve_null_V"])
    result = writer = None
    try:
        plant.reset(comp.x0_m, comp.u_init_V, t0_s=-comp.n_warm * ts)
        # on disk every 0.1 s of samples: a hard kill loses at most that
        writer = RecordingWriter(rec_path, meta, columns, flush_every=max(1, round(0.1 / ts)))
        with scope:
            result = run_loop(plant, comp.reference, comp.controller, comp.estimators, comp.to_output,
                              comp.to_input, pacing=pacing, n_warm=comp.n_warm, writer=writer,
                              status=StatusLine(interval_s=float(m["status_interval_s"])) if status else None,
                              overrun_budget=budget, null_V=null_V, stop_after=stop_after)
        return result
    finally:
        if result is None:
            # stopped outside the loop (Ctrl-C or SIGTERM between the reset and the first sample, a writer
            # that could not open its file): the loop's own stop did not run, so send the valve to null here
            safe = getattr(plant, "safe_stop", None)
            if safe is not None:
                try:
                    safe(null_V)
                except Exception:  # noqa: BLE001 - the first problem is the one to report
                    pass
        if writer is not None:
            writer.close()
        close = getattr(plant, "close", None)
        if close is not None:
            close()


def _write_results(out: Path, res: LoopResult, summary: dict) -> None:
    """``coefficients.npz`` (every estimator's theta after every sample, the timing) and ``summary.json``."""
    with atomic_path(out / "coefficients.npz") as tmp:
        np.savez(tmp, time_s=np.arange(res.n_samples) * res.sample_time_s,
                 lateness_s=res.lateness_s, latency_s=res.latency_s, compute_s=res.compute_s,
                 **{f"theta_{slug(name)}": th for name, th in res.thetas.items()})
    write_json_atomic(out / "summary.json", summary, indent=2, default=_json_default, trailing_newline=True)


def _json_default(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    raise TypeError(type(x))


def identified_models(result: LoopResult, estimators: dict) -> dict:
    """Final ``theta`` of each estimator as ``a1..an``, ``b1..bn`` and the transfer function text (eqs. 9-11)."""
    out = {}
    for name, est in estimators.items():
        th = result.thetas[name]
        if not th.shape[0]:
            continue
        theta = th[-1]
        n = theta.size // 2
        a, b = theta[:n], theta[n:]
        out[name] = {"order": n, "a": a.tolist(), "b": b.tolist(), "theta": theta.tolist(),
                     "transfer_function": transfer_function_text(a, b), "finite": bool(np.isfinite(theta).all())}
    return out


def _term(c: float, power: int, first: bool) -> str:
    z = "" if power == 0 else ("z" if power == 1 else f"z^{power}")
    mag = f"{abs(c):.5g}"
    body = f"{mag} {z}".strip() if z else mag
    sign = ("-" if c < 0 else "") if first else (" - " if c < 0 else " + ")
    return sign + body


def transfer_function_text(a, b) -> str:
    """``G(z) = (b1 z^n + ... + bn z) / (z^n + a1 z^(n-1) + ... + an)``, 5 significant digits, as paper 1 prints
    eqs. 9-11 (the same model as ``B(z^-1)/A(z^-1)`` of eq. 6 up to one sample of delay, see the report)."""
    n = len(a)
    num = "".join(_term(b[i], n - i, i == 0) for i in range(n))
    den = "z" + (f"^{n}" if n > 1 else "") + "".join(_term(a[i], n - 1 - i, False) for i in range(n))
    return f"G(z) = ({num}) / ({den})"


def _summary(spec, res: LoopResult, comp, choice, plant, mode, rec_path, pred_keys, pred_cols) -> dict:
    y = comp.to_output(res.position_m)
    preds = {}
    for (name, h), col in zip(pred_keys, pred_cols):
        st = error_stats(y, res.predictions[(name, h)]) if res.n_samples else {}
        preds[col] = {"estimator": name, "h": h, **st}
    plant_counts = {}
    for key in ("lost", "late", "clipped"):
        if hasattr(plant, key):
            plant_counts[key] = int(getattr(plant, key))
    rtt = getattr(plant, "rtt_s", None)
    if rtt:
        r = np.asarray(rtt)
        plant_counts["rtt_s"] = {"p50": float(np.percentile(r, 50)), "p99": float(np.percentile(r, 99)),
                                 "max": float(r.max())}
    if hasattr(plant, "commands_V"):
        plant_counts["commands_logged"] = len(plant.commands_V)
    return {"name": spec["mre"]["name"], "plant": choice.text, "mode": mode, "pacing": res.pacing,
            "stop_reason": res.stop_reason, "error": res.error, "valve_to_null": res.valve_to_null,
            "samples": res.n_samples, "samples_planned": res.n_planned, "recording": str(rec_path.name),
            "held_samples": int(res.plant_flag.sum()), "timing": timing_summary(res), "plant_counts": plant_counts,
            "wall_time_s": res.wall_time_s, "identified": identified_models(res, comp.estimators),
            "predictions": preds}
