"""Continuous-time transfer-function estimation from sampled data (MATLAB ``tfest``).

Model ``y(t) = B(s)/A(s) u(t - tau) + e(t)`` with ``A(s) = s^np + a_1 s^(np-1) + ... + a_np``
and ``B(s) = b_0 s^nz + ... + b_nz``; the input is held between samples
(zero-order hold), the delay ``tau`` is a whole number of samples.

Algorithm:

1. delay (when not given): scan of discrete output-error models (Steiglitz–
   McBride) over ``0 .. max_delay_samples``, then the best delay and its two
   neighbours are refined and the one with the smallest final cost is kept;
2. start: poles of a discrete output-error model mapped by ``s = log(z)/Ts``;
3. SRIVC (simplified refined instrumental variables, Young & Jakeman 1980;
   Garnier & Young 2014): signals filtered by ``s^k / A(s)``, instruments from
   the noise-free model output, a few iterations;
4. prediction-error refinement of the simulation error (output-error noise
   model) by Levenberg–Marquardt (``scipy.optimize.least_squares``) on the
   exact zero-order-hold discretisation; covariance ``sigma^2 (J^T J)^-1``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import cont2discrete, lfilter

from ._blas import one_blas_thread
from ._checks import check_data, check_enough_data, check_order, scaled
from ._diagnose import finish
from .data import IDData, check_sample_time, real_number
from .errors import SysidError
from .polynomial import IDPoly, coefficients, std_of

__all__ = ["IDTF", "TFEst", "tfest"]


@dataclass
class IDTF:
    """Continuous-time transfer function ``num(s)/den(s) e^{-s iodelay}``.

    Attributes
    ----------
    num : ndarray, shape (nz+1,)
        Numerator coefficients, highest power of ``s`` first.
    den : ndarray, shape (np+1,)
        Monic denominator, highest power first.
    iodelay : float
        Input delay in seconds.
    Ts : float
        Sample time (s) of the data; used to evaluate the model on sampled data (ZOH).
    covariance : ndarray or None, shape (d, d)
        Covariance of ``[a_1..a_np, b_0..b_nz]`` (:attr:`parameters`).
    noise_variance : float
        Variance of the output error.
    """

    num: np.ndarray
    den: np.ndarray
    iodelay: float = 0.0
    Ts: float = 1.0
    covariance: np.ndarray | None = None
    noise_variance: float = 0.0
    loss: float = float("nan")
    n_samples: int = 0
    report: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    def __post_init__(self):
        self.num = coefficients(self.num, "num")
        self.den = coefficients(self.den, "den")
        if self.den.size == 0 or self.den[0] != 1.0:
            raise SysidError(f"den must be monic (first coefficient 1, highest power of s first), got {self.den!r}.")
        if self.num.size >= self.den.size:
            raise SysidError(f"num must have a lower degree than den (strictly proper), got {self.num.size - 1} "
                             f"and {self.den.size - 1}.")
        self.Ts = check_sample_time(self.Ts)
        delay = real_number(self.iodelay, "iodelay", "a non-negative number of seconds")
        if not (np.isfinite(delay) and delay >= 0):
            raise SysidError(f"iodelay must be a non-negative number of seconds, got {self.iodelay!r}.")
        self.iodelay = delay

    @property
    def parameters(self) -> np.ndarray:
        """``[a_1..a_np, b_0..b_nz]``, shape (d,)."""
        return np.r_[self.den[1:], self.num]

    @property
    def n_parameters(self) -> int:
        return self.den.size - 1 + self.num.size

    @property
    def std(self) -> np.ndarray | None:
        """Standard deviations of :attr:`parameters`."""
        return std_of(self.covariance)

    @property
    def delay_samples(self) -> int:
        return int(round(self.iodelay / self.Ts))

    def to_idpoly(self, Ts=None) -> IDPoly:
        """Zero-order-hold equivalent output-error model ``B(q)/F(q)`` with the delay in ``nk``.

        Parameters
        ----------
        Ts : float or None
            Sample time in seconds (default: the estimation data's ``self.Ts``).  The
            delay must be a whole number of these samples (it is exact then).
        """
        if Ts is None:
            return _discretise(self.num, self.den, self.Ts, self.delay_samples)
        Ts = check_sample_time(Ts)
        d = self.iodelay / Ts
        if abs(d - round(d)) > 1e-6 * max(1.0, d):
            raise SysidError(f"the model's input delay {self.iodelay:g} s is not a whole number of samples of "
                             f"Ts = {Ts:g} s, so its sampled form is not exact: use data sampled at a divisor of "
                             f"the delay.")
        return _discretise(self.num, self.den, Ts, int(round(d)))

    def to_lti_continuous(self):
        """(num, den, 0) for :mod:`sysid.convert` (the delay is not represented)."""
        return self.num.copy(), self.den.copy(), 0

    def __repr__(self) -> str:
        """MATLAB-style display: the transfer function, input delay, parameterization, status."""
        from ._display import status_block

        def spoly(c):
            c = np.asarray(c, float)
            n = c.size - 1
            terms = []
            for k, v in enumerate(c):
                p = n - k
                if v == 0.0:
                    continue
                mag = f"{abs(v):.4g}"
                t = mag + (" s" if p == 1 else f" s^{p}" if p > 1 else "")
                if p and abs(v) == 1.0:
                    t = t[len(mag) + 1:]
                terms.append(t if not terms and v > 0 else ("-" + t if not terms else ("- " if v < 0 else "+ ") + t))
            return " ".join(terms) or "0"

        num, den = spoly(self.num), spoly(self.den)
        width = max(len(num), len(den))
        pre = f"exp(-{self.iodelay:g}*s) * " if self.iodelay else ""
        pad = " " * len(pre)
        lines = ["Continuous-time identified transfer function.", "",
                 f"  {pad}{num:^{width}}", f"  {pre}{'-' * width}", f"  {pad}{den:^{width}}", "",
                 f"Input delay: {self.iodelay:g} seconds ({self.delay_samples} samples of {self.Ts:g} s)", "",
                 "Parameterization:",
                 f"   Number of poles: {self.den.size - 1}   Number of zeros: {self.num.size - 1}",
                 f"   Number of free coefficients: {self.n_parameters}", ""]
        lines += status_block(self, "TFEST", f"time domain data sampled at {self.Ts:g} s")
        return "\n".join(lines)

    __str__ = __repr__

    def poles(self) -> np.ndarray:
        """Poles in the s-plane (rad/s)."""
        return np.roots(self.den)

    def zeros(self) -> np.ndarray:
        """Zeros in the s-plane (rad/s)."""
        return np.roots(np.trim_zeros(self.num, "f")) if self.num.size > 1 else np.zeros(0)

    def freqresp(self, omega) -> np.ndarray:
        """``G(j omega) e^{-j omega iodelay}`` at ``omega`` in rad/s."""
        s = 1j * np.asarray(omega, dtype=float)
        return np.polyval(self.num, s) / np.polyval(self.den, s) * np.exp(-s * self.iodelay)

    def dcgain(self) -> float:
        """Static gain ``b_nz / a_np``."""
        return float(self.num[-1] / self.den[-1])


def _discretise(num, den, Ts, d) -> IDPoly:
    numd, dend, _ = cont2discrete((np.asarray(num, float), np.asarray(den, float)), Ts, method="zoh")
    numd = np.ravel(numd)
    numd = np.r_[np.zeros(dend.size - numd.size), numd]
    numd[0] = 0.0  # strictly proper (ZOH of a proper CT system with nz < np)
    B = np.r_[np.zeros(d), numd]
    return IDPoly([1.0], B, F=dend, Ts=Ts, nk=d + 1, nb=B.size - d - 1, structure="oe")


def _filter(sig, k, den, Ts, method):
    """Sampled ``s^k / den(s)`` applied to ``sig`` (``0 <= k <= deg den``)."""
    num = np.zeros(k + 1)  # s^k, highest power first
    num[0] = 1.0
    bd, ad, _ = cont2discrete((num, den), Ts, method=method)
    return lfilter(np.ravel(bd), ad, sig)


def _srivc(y, u, den, n, m, Ts, iterations):
    """SRIVC iterations from the denominator ``den``; returns (den, num)."""
    # numerator for the starting denominator: y ~ sum_j b_j s^(m-j)/den u (linear LS)
    uphi = [_filter(u, k, den, Ts, "zoh") for k in range(m, -1, -1)]
    num = np.linalg.lstsq(np.column_stack(uphi), y, rcond=None)[0]
    start = (den.copy(), num.copy())
    th = None
    for it in range(iterations):
        if it:
            uphi = [_filter(u, k, den, Ts, "zoh") for k in range(m, -1, -1)]
        ycols = [_filter(y, k, den, Ts, "bilinear") for k in range(n + 1)]
        phi = np.column_stack([-ycols[k] for k in range(n - 1, -1, -1)] + uphi)
        x = lfilter(*_zoh_ba(num, den, Ts), u)  # instruments: noise-free model output
        xcols = [_filter(x, k, den, Ts, "bilinear") for k in range(n)]
        zeta = np.column_stack([-xcols[k] for k in range(n - 1, -1, -1)] + uphi)
        try:
            th = np.linalg.solve(zeta.T @ phi, zeta.T @ ycols[n])
        except np.linalg.LinAlgError:
            break
        new_den = np.r_[1.0, th[:n]]
        if np.any(np.roots(new_den).real >= 0):
            break
        den, num = new_den, th[n:]
    return (den, num), start


def _zoh_ba(num, den, Ts):
    p = _discretise(num, den, Ts, 0)
    return p.B, p.F


class TFEst:
    """Continuous-time transfer-function estimator: ``TFEst(np, nz, iodelay).fit(data)``.

    Parameters
    ----------
    n_poles : int
        Number of poles ``np >= 1``.
    n_zeros : int
        Number of zeros ``0 <= nz < np``.
    iodelay : float or None
        Input delay in seconds (rounded to whole samples); ``None`` estimates it.
    max_delay_samples : int
        Largest delay tried when estimating it.
    srivc_iterations : int
        SRIVC iterations before the prediction-error refinement.
    """

    def __init__(self, n_poles, n_zeros=0, iodelay=None, max_delay_samples=20, srivc_iterations=6):
        self.n_poles = n_poles
        self.n_zeros = n_zeros
        self.iodelay = iodelay
        self.max_delay_samples = max_delay_samples
        self.srivc_iterations = srivc_iterations

    def _scan_delay(self, data, n):
        """Delay (samples) of the discrete OE model [nb=np nf=np nk=1+d] with least simulation error."""
        from .pem import steiglitz_mcbride
        best, best_d = np.inf, 0
        dmax = check_order(self.max_delay_samples, "max_delay_samples")
        y = data.y[dmax:]
        for d in range(dmax + 1):
            B, F = steiglitz_mcbride(data.y, data.u, n, n, 1 + d, iterations=4)
            e = y - lfilter(B, F, data.u)[dmax:]
            cost = float(e @ e)
            if cost < best:
                best, best_d = cost, d
        return best_d

    def _fit_delay(self, data, d):
        n, m, Ts = self.n_poles, self.n_zeros, data.Ts
        y, u = data.y, np.r_[np.zeros(d), data.u[:data.N - d]]
        from .pem import steiglitz_mcbride
        _, F = steiglitz_mcbride(y, u, n, n, 1)
        zp = np.roots(F) if F.size > 1 else np.zeros(0)
        sp = np.log(np.clip(np.abs(zp), 1e-6, 0.999999)) / Ts + 1j * np.angle(zp) / Ts
        sp = np.where(np.abs(np.angle(zp)) > 3.1, np.log(np.clip(np.abs(zp), 1e-6, 0.9999)) / Ts, sp)
        den = np.real(np.poly(sp)) if sp.size == n else np.real(np.poly(-np.ones(n) / Ts / 10))
        (den, num), (den0, num0) = _srivc(y, u, den, n, m, Ts, self.srivc_iterations)

        big = 1e3 * (np.abs(y) + np.std(y) + 1.0)

        def res(th):
            den_ = np.r_[1.0, th[:n]]
            if np.any(den_ <= 0) or np.any(np.roots(den_).real >= 0):
                return big  # unstable candidate: rejected by the trust region
            p = _discretise(th[n:], den_, Ts, 0)
            return y - lfilter(p.B, p.F, u)

        sol = least_squares(res, np.r_[den[1:], num], method="lm", x_scale="jac")
        x_start = np.r_[den0[1:], num0]
        r0 = res(x_start)
        if float(sol.fun @ sol.fun) > float(r0 @ r0):  # SRIVC went astray: restart from the OE start
            sol = least_squares(res, x_start, method="lm", x_scale="jac")
        return sol

    @one_blas_thread
    def fit(self, data: IDData) -> IDTF:
        """Estimate; sets ``model_`` and returns an :class:`IDTF`."""
        data = check_data(data)
        n = check_order(self.n_poles, "np", 1)
        m = check_order(self.n_zeros, "nz")
        if m >= n:
            raise SysidError(f"nz must be smaller than np = {n} (proper, strictly), got {m}.")
        dmax = check_order(self.max_delay_samples, "max_delay_samples")
        check_order(self.srivc_iterations, "srivc_iterations")
        check_enough_data(data.N - dmax, n + m + 1, f"tfest with {n} poles and {m} zeros")
        original = data
        data, sy, su = scaled(data)
        Ts = data.Ts
        if self.iodelay is None:
            d0 = self._scan_delay(data, n)
            candidates = sorted({max(d0 - 1, 0), d0, d0 + 1})
        else:
            try:
                delay = real_number(self.iodelay, "iodelay", "a non-negative number of seconds or None")
            except SysidError:
                delay = float("nan")
            if not (np.isfinite(delay) and delay >= 0):
                raise SysidError(f"iodelay must be a non-negative number of seconds or None, got {self.iodelay!r}.")
            candidates = [int(round(delay / Ts))]
        best = None
        for d in candidates:
            sol = self._fit_delay(data, d)
            cost = float(sol.fun @ sol.fun)
            if best is None or cost < best[0]:
                best = (cost, d, sol)
        cost, d, sol = best
        N, dpar = data.N, n + m + 1
        lam = cost / max(N - dpar, 1)
        J = sol.jac
        try:
            cov = lam * np.linalg.inv(J.T @ J)
        except np.linalg.LinAlgError:
            cov = None
        g = sy / su
        if cov is not None:
            w = np.r_[np.ones(n), np.full(m + 1, g)]
            cov = cov * np.outer(w, w)
        model = IDTF(sol.x[n:] * g, np.r_[1.0, sol.x[:n]], iodelay=d * Ts, Ts=Ts, covariance=cov,
                     noise_variance=lam * sy ** 2, loss=cost / N * sy ** 2, n_samples=N,
                     report=dict(nfev=sol.nfev, delay_candidates=candidates))
        finish(model, original, f"tfest model ({n} poles, {m} zeros)", focus="simulation")
        self.model_ = model
        return model


def tfest(data: IDData, np, nz=0, iodelay=None) -> IDTF:  # noqa: F811 (MATLAB name)
    """MATLAB ``tfest(data, np, nz, iodelay)``: continuous-time transfer function.

    Parameters
    ----------
    data : IDData
    np : int
        Number of poles (MATLAB's argument name; shadows numpy only in here).
    nz : int
        Number of zeros (``< np``).
    iodelay : float or None
        Input delay in seconds; ``None`` (default) estimates it.

    Returns
    -------
    IDTF
    """
    return TFEst(np, nz, iodelay).fit(data)
