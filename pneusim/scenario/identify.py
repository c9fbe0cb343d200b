"""Identifiers scored by a scenario, and the metrics they are scored with.

Every identifier returns a list of *rows* (dicts): ``identifier``, ``reading``,
``status`` (``ok`` or ``not available`` / ``failed`` with ``reason``), metrics
(``fit_percent``, ``mse`` ...) and, under ``_yhat``, the model output on the
validation data (dropped before JSON).  Black-box identifiers come from
:mod:`sysid` (MATLAB-style surface); a function missing there makes the row
``not available`` instead of stopping the run.

Fit in percent is MATLAB's ``compare`` fit, ``100 (1 - ||y - yhat|| / ||y - mean(y)||)``.
"""

from __future__ import annotations

import math
import traceback

import numpy as np
import sysid
from scipy import signal as sps

from ..errors import PneusimError
from ..fit import fit_recording
from ..metrics import error_stats, fit_percent
from ..simulate import rerun_recording
from .analysis import band_behaviour, band_response, free_run, s_reading, z_properties

__all__ = ["run_blackbox", "score_published_z", "score_published_s", "run_physical_fit", "not_available",
           "clean_row"]


def not_available(ident: dict, reason: str, status: str = "not available") -> dict:
    return {"identifier": ident["name"], "kind": ident["kind"], "reading": "", "status": status, "reason": reason}


_SYSID_FUN = {"arx": "arx", "armax": "armax", "ss": "n4sid", "tf": "tfest"}


def run_blackbox(ident: dict, est: tuple, val: tuple, ts: float) -> list[dict]:
    """Estimate a :mod:`sysid` model on ``est = (y, u)``, simulate it on ``val = (y, u)``, score it.

    The simulation starts from estimated initial conditions where :func:`sysid.simulate`
    offers them (MATLAB's ``compare`` default), else from zero.
    """
    fun = _SYSID_FUN[ident["kind"]]
    missing = [f for f in ("iddata", fun, "simulate") if not hasattr(sysid, f)]
    if missing:
        return [not_available(ident, f"sysid has no {', '.join(missing)} yet")]
    try:
        d_est = sysid.iddata(est[0], est[1], ts)
        d_val = sysid.iddata(val[0], val[1], ts)
        if ident["kind"] in ("arx", "armax"):
            model = getattr(sysid, fun)(d_est, list(ident["orders"]))
        elif ident["kind"] == "ss":
            model = sysid.n4sid(d_est, ident["nx"])
        else:
            model = sysid.tfest(d_est, ident["np"], ident["nz"], iodelay=ident.get("iodelay_s"))
        try:
            yhat = np.asarray(sysid.simulate(model, d_val, initial="estimate"), float).ravel()
            init = "estimated"
        except Exception:  # noqa: BLE001 - an identifier without estimated initial conditions
            yhat = np.asarray(sysid.simulate(model, d_val), float).ravel()
            init = "zero"
        row = {"identifier": ident["name"], "kind": ident["kind"], "reading": f"simulation, {init} initial state",
               "status": "ok", **error_stats(val[0], yhat), "_yhat": yhat, "_model": model, **_model_g(model)}
        if hasattr(sysid, "compare"):
            try:
                row["fit_percent_sysid_compare"] = float(sysid.compare(d_val, model))
            except Exception:  # noqa: BLE001
                pass
        return [row]
    except Exception as exc:  # noqa: BLE001 - an identifier failing must not stop the scenario
        return [not_available(ident, f"{type(exc).__name__}: {exc} "
                              f"({traceback.extract_tb(exc.__traceback__)[-1].name})", status="failed")]


def _model_g(model) -> dict:
    """The model's input-output transfer function ``G = B/(A F)`` (descending powers of z^-1) as
    ``model_num``, ``model_den``, so that a reader can re-simulate it; empty if sysid cannot say."""
    try:
        poly = model if hasattr(model, "G") else model.to_idpoly()
        num, den = poly.G()
        return {"model_num": [float(v) for v in np.ravel(num)], "model_den": [float(v) for v in np.ravel(den)]}
    except Exception:  # noqa: BLE001 - the polynomials are extra information
        return {}


def _published_one_step(num, den, y, u, input_delay):
    """One-step prediction of ``A(z) y = B(z) u`` with the printed z-polynomials (descending powers).

    ``yhat(k) = y(k) - (A(q) y)(k) + (B(q) u)(k)``, i.e. ``-a1 y(k-1) - ... + b0 u(k-d) + ...``;
    ``num`` is padded on the left to the length of ``den``; ``input_delay`` (d) samples shift ``u``.
    The first ``n + d`` samples (incomplete regressor) are NaN.
    """
    den = np.asarray(den, float) / den[0]
    num = np.concatenate((np.zeros(len(den) - len(num) + input_delay), np.asarray(num, float))) / den[0]
    yhat = y - sps.lfilter(den, [1.0], y) + sps.lfilter(num, [1.0], u)
    yhat[:len(den) - 1 + input_delay] = np.nan
    return yhat


def score_published_z(ident: dict, y: np.ndarray, u: np.ndarray, warmup: int = 0) -> list[dict]:
    """Paper 1 equations 9-11 on our data: one-step prediction and free-run simulation.

    Two readings: *as printed* (the numerator's leading term multiplies ``u(k)``)
    and *eq. 6* (regressor ``u(k-1) ... u(k-n)``, one sample later), each for
    every input offset in ``ident['input_offsets']`` (e.g. the valve null).  The free run
    (``_free``) starts from the first sample (deviation variables), so the offset does not change it.
    """
    rows = []
    num, den = ident["num"], ident["den"]
    readings = [(off, d, r) for off in ident.get("input_offsets", [0.0])
                for d, r in ((0, "as printed"), (1, "eq. 6 regressor (one-sample delay)"))]
    for offset, delay, reading in readings:
        reading = f"{reading}, u - {offset:g}" if offset else reading
        yhat = _published_one_step(num, den, y, u - offset, delay)
        yhat[:warmup] = np.nan
        row = {"identifier": ident["name"], "kind": ident["kind"], "reading": reading, "status": "ok",
               "input_offset": float(offset), "input_delay_samples": delay,
               **error_stats(y, yhat), "_yhat": yhat}
        free = free_run(num, den, y, u, delay)
        row["free_run_fit_percent"] = fit_percent(y, free) if np.all(np.isfinite(free)) else float("nan")
        row["_free"] = free
        row.update(z_properties(num, den))
        rows.append(row)
    return rows


_UNIT_S = {"s": lambda ts: 1.0, "ms": lambda ts: 1e-3, "sample": lambda ts: ts}


def score_published_s(ident: dict, val: tuple, ts: float, record_s: float | None = None,
                      band_Hz=None, output_per_m: float | None = None) -> list[dict]:
    """Paper 2 equation 4 under each time-unit reading, simulated (zero state) on the validation data.

    If ``s`` and the delay are in units of ``T`` seconds, ``G_T(s_T)`` becomes
    ``G(s T)`` in seconds (coefficient of ``s^i`` times ``T^i``) with a delay of
    ``delay T`` seconds.  The row records poles in rad/s, the DC gain, the damping of
    complex poles, the slowest time constant against the record length ``record_s``
    (default: the validation data's), the frequency response over ``band_Hz`` (the
    excitation band) with what it behaves like there, and the fit.  With ``output_per_m``
    (output units per metre of piston travel) the integrator-like gain is also given in
    mm/s per input unit.
    """
    y, u = val
    rows = []
    record_s = len(y) * ts if record_s is None else float(record_s)  # the whole experiment, for the behaviour
    for unit in ident.get("time_units", ["s"]):
        T = _UNIT_S[unit](ts)
        num_s, den_s = s_reading(ident["num"], ident["den"], T)
        delay_s = float(ident.get("delay", 0.0)) * T
        nd = int(round(delay_s / ts))
        poles = np.roots(den_s)
        stable = bool(np.all(poles.real < 0))
        slowest = float(1.0 / np.min(np.abs(poles.real))) if stable else float("inf")
        cplx = [p for p in poles if abs(p.imag) > 1e-12]
        band = band_response(num_s, den_s, band_Hz or [])
        if output_per_m:
            for b in band:
                b["velocity_gain_mm_per_s"] = 1e3 * b["gain_x_omega"] / output_per_m
        row = {"identifier": ident["name"], "kind": ident["kind"], "reading": f"time unit = {unit}",
               "status": "ok", "time_unit_s": T, "delay_s": delay_s, "delay_samples": nd,
               "dc_gain": float(num_s[-1] / den_s[-1]), "poles_rad_per_s": [str(complex(p)) for p in poles],
               "damping_ratio_min": float(min(-p.real / abs(p) for p in cplx)) if cplx else None,
               "slowest_time_constant_s": slowest, "record_s": record_s, "stable": stable,
               "band": band, "behaviour": band_behaviour(band, stable, delay_s, record_s)}
        if nd >= len(y):
            row.update(status="ok", fit_percent=float("nan"), reason="the delay is longer than the record")
            rows.append(row)
            continue
        bd, ad, _ = sps.cont2discrete((num_s, den_s), ts, method="zoh")
        ud = np.concatenate((np.zeros(nd), u))[:len(u)]
        yhat = sps.lfilter(np.ravel(bd), np.ravel(ad), ud)
        row.update(error_stats(y, yhat))
        row["_yhat"] = yhat
        rows.append(row)
    return rows


def run_physical_fit(ident: dict, rec, n_est: int, rig, effects, to_output, val_y) -> list[dict]:
    """Fit the physical model (:func:`pneusim.fit.fit_recording`) on the estimation part and score it
    the way the black-box models are scored: the fitted rig re-runs the recording's experiment from
    its start (closed loop: the reference through the controller, as the black-box models map the
    scenario's input to the position) and is scored on the validation part.  Re-running from the
    start, not from the split, matters: the piston is at rest at the start of the experiment but
    may be moving at the split, where a re-run would have to start from rest.  The row also carries the fit's own validation (the recorded command
    simulated from the state the fit estimated at the split), estimates with standard errors, and
    the fit's identifiability warnings.
    """
    try:
        options = {"starts": ident["fit_starts"]} if ident.get("fit_starts") else {}
        result = fit_recording(rec, rig, effects, validation_fraction=(rec.n_samples - n_est) / rec.n_samples,
                               quiet=True, **options)   # a sweep has its own progress bar
        sim = rerun_recording(result.rig_, rec, result.effects_, noise_scale=0.0)
    except PneusimError as exc:
        return [not_available(ident, str(exc), status="failed")]
    except Exception as exc:  # noqa: BLE001 - a fit that crashes must not take the other identifiers down
        return [not_available(ident, f"{type(exc).__name__}: {exc} "
                              f"({traceback.extract_tb(exc.__traceback__)[-1].name})", status="failed")]
    yhat = to_output(sim.recording.position_m[n_est:])
    return [{"identifier": ident["name"], "kind": ident["kind"],
             "reading": "fitted rig, experiment re-run, scored on validation", "status": "ok",
             **error_stats(val_y, yhat), "_yhat": yhat, "_fit": result,
             "model_effects": [e.to_text() for e in effects],
             "fit_percent_recorded_command": result.fit_percent,
             "fit_seconds": result.solver["seconds"], "solver_status": result.solver["status"],
             "estimates": {k: {"estimate": p.estimate, "std": p.std, "start": p.start}
                           for k, p in result.parameters.items()},
             "fit_warnings": list(result.warnings)}]


def clean_row(row: dict) -> dict:
    """The row without private arrays, NaN/inf as None (strict JSON)."""
    out = {}
    for k, v in row.items():
        if k.startswith("_"):
            continue
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        out[k] = v
    return out
