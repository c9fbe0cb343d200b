"""Numbers the reports reason with: properties of linear models and of the simulated rig.

* discrete models (paper 1's eqs. 9-11 and the final RLS estimates): DC gain, largest pole
  modulus, free-run simulation from the first sample;
* continuous models (paper 2's eq. 4) under a time-unit reading: the frequency response over
  the excitation band, and whether the model behaves there like an integrator (what a
  valve-driven cylinder is, from valve command to position) or like a static gain (type 0,
  what a closed position loop is);
* the simulated rig: its velocity gain per volt of valve command around the null, from an
  open-loop recording.

Everything here is computed from the models and the data, never asserted.
"""

from __future__ import annotations

import numpy as np
from scipy import signal as sps

__all__ = ["theta_to_z", "z_properties", "free_run", "s_reading", "band_response", "band_behaviour",
           "valve_velocity_gain", "excitation_freqs_Hz"]


def theta_to_z(theta, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``theta = [a1..an, b1..bn]`` of paper 1's eq. 6 as ``(num, den)`` in descending powers of z.

    ``A = 1 + a1 z^-1 + ... + an z^-n``, ``B = b1 z^-1 + ... + bn z^-n``: multiplied by ``z^n``,
    ``den = [1, a1..an]`` and ``num = [0, b1..bn]``.
    """
    theta = np.asarray(theta, float)
    return np.concatenate(([0.0], theta[n:])), np.concatenate(([1.0], theta[:n]))


def z_properties(num, den) -> dict:
    """DC gain ``B(1)/A(1)`` and the largest pole modulus of a discrete model."""
    num, den = np.asarray(num, float), np.asarray(den, float)
    s_den = float(np.sum(den))
    poles = np.roots(den)
    return {"dc_gain": float(np.sum(num) / s_den) if abs(s_den) > 1e-12 else float("inf"),
            "poles_abs_max": float(np.max(np.abs(poles))) if poles.size else 0.0}


def free_run(num, den, y, u, delay: int = 0) -> np.ndarray:
    """Simulate ``num/den`` (descending powers of z, ``num`` padded on the left) on ``u`` alone,
    in deviation from the first sample: ``y(0) + G (u - u(0))``; NaN if it diverges."""
    num, den = np.asarray(num, float), np.asarray(den, float)
    nn = np.concatenate((np.zeros(len(den) - len(num) + delay), num))
    with np.errstate(all="ignore"):
        out = y[0] + sps.lfilter(nn, den, np.asarray(u, float) - u[0])
    return out if np.all(np.isfinite(out)) else np.full(len(u), np.nan)


def s_reading(num, den, T: float) -> tuple[np.ndarray, np.ndarray]:
    """A continuous model whose time unit is ``T`` seconds, rewritten in seconds (monic denominator).

    ``G_T(s_T)`` with ``s_T = s T`` multiplies the coefficient of ``s^i`` by ``T^i``.
    """
    num, den = np.asarray(num, float), np.asarray(den, float)
    num_s = num * T ** np.arange(len(num) - 1, -1, -1)
    den_s = den * T ** np.arange(len(den) - 1, -1, -1)
    return num_s / den_s[0], den_s / den_s[0]


def band_response(num_s, den_s, freqs_Hz) -> list[dict]:
    """``G(j 2 pi f)`` at each frequency (delay left out): gain, phase in degrees, and gain x omega
    (the velocity gain an integrator ``K/s`` would have: K)."""
    out = []
    for f in freqs_Hz:
        w = 2.0 * np.pi * f
        g = np.polyval(num_s, 1j * w) / np.polyval(den_s, 1j * w)
        out.append({"f_Hz": float(f), "gain": float(abs(g)), "phase_deg": float(np.degrees(np.angle(g))),
                    "gain_x_omega": float(abs(g) * w)})
    return out


def band_behaviour(band: list[dict], stable: bool, delay_s: float, record_s: float, tol_deg: float = 30.0) -> str:
    """What the model does over the excitation band, from the phase at its lowest frequency.

    ``integrator`` (phase within ``tol_deg`` of -90 degrees: velocity follows the input),
    ``type 0`` (phase within ``tol_deg`` of 0: a static gain), else ``neither``; a dead time of
    10 % of the record or more is named first.
    """
    parts = []
    if delay_s >= 0.1 * record_s:
        parts.append(f"dead time {delay_s:g} s = {100 * delay_s / record_s:.0f} % of the record")
    if not stable:
        parts.append("unstable")
    elif band:
        lo = band[0]
        if abs(lo["phase_deg"] + 90.0) <= tol_deg:
            parts.append(f"integrator over the band (phase {lo['phase_deg']:.0f} deg at {lo['f_Hz']:g} Hz)")
        elif abs(lo["phase_deg"]) <= tol_deg:
            parts.append(f"type 0 over the band (static gain {lo['gain']:.3g}, phase {lo['phase_deg']:.0f} deg "
                         f"at {lo['f_Hz']:g} Hz)")
        else:
            # worded without "integrator" / "type 0": the report's tables classify readings by those words
            parts.append(f"neither integrating nor a static gain (phase {lo['phase_deg']:.0f} deg at {lo['f_Hz']:g} Hz)")
    return "; ".join(parts)


def valve_velocity_gain(position_m, valve_cmd_V, sample_time_s: float, null_V: float, stroke_m: float,
                        margin_m: float = 5e-3, skip: int = 50) -> dict | None:
    """Least-squares ``v = K (u - null)`` on an open-loop recording, away from the end stops.

    Returns ``{"gain_m_per_s_per_V", "r2", "n"}`` or ``None`` with too few samples.  This is
    the integrator gain of the rig from valve command to position (what eq. 4's readings are
    compared with).
    """
    x = np.asarray(position_m, float)
    u = np.asarray(valve_cmd_V, float) - null_V
    v = np.gradient(x, sample_time_s)
    ok = (x > margin_m) & (x < stroke_m - margin_m)
    ok[:skip] = False
    if ok.sum() < 20 or not np.any(u[ok] != 0):
        return None
    k = float(np.sum(v[ok] * u[ok]) / np.sum(u[ok] ** 2))
    res = v[ok] - k * u[ok]
    return {"gain_m_per_s_per_V": k, "r2": float(1.0 - np.var(res) / np.var(v[ok])), "n": int(ok.sum())}


def excitation_freqs_Hz(signal_spec: dict, record_s: float) -> list[float]:
    """The band a model is judged on: a multisine's distinct frequencies, else 1/record to 10/record."""
    if signal_spec.get("kind") == "multisine":
        freqs = sorted({float(c[1]) for c in signal_spec["components"] if c[1] > 0})
        if freqs:
            return freqs
    return [1.0 / record_s, 10.0 / record_s]
