"""Polynomial black-box model ``A(q) y = B(q)/F(q) u + C(q)/D(q) e`` (MATLAB ``idpoly``).

Conventions (as MATLAB prints them): polynomials in the backward shift
``q^-1``, coefficient arrays start with the ``q^0`` coefficient; ``A``, ``C``,
``D``, ``F`` are monic (leading 1); ``B`` carries ``nk`` leading zeros, so
``B = [0]*nk + [b_nk, ..., b_{nk+nb-1}]``.  ``e`` is white noise with
variance ``noise_variance``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .data import check_sample_time
from .errors import SysidError

__all__ = ["IDPoly", "idpoly"]

_ONE = np.ones(1)


def coefficients(p, name: str) -> np.ndarray:
    """Real polynomial coefficients as a 1-D float array (complex, text or a matrix refused)."""
    try:
        a = np.asarray(p)
        vector = a.ndim <= 1 or (a.ndim == 2 and 1 in a.shape)
        a = np.atleast_1d(a.astype(float)).ravel() if vector and a.dtype.kind in "biufO" else None
    except (TypeError, ValueError):
        a = None
    if a is None:
        raise SysidError(f"{name} must be a 1-D array of real coefficients, got {p!r}.")
    return a


def _monic(p, name: str) -> np.ndarray:
    p = coefficients(p, name)
    if p.size == 0:
        return _ONE.copy()
    if p[0] != 1.0:
        raise SysidError(f"{name} must be monic (first coefficient 1), got {p[0]!r}.")
    return p


def is_stable_poly(p: np.ndarray, margin: float = 1.0) -> bool:
    """True when all roots of ``p(q^-1)`` in ``z`` lie strictly inside radius ``margin``."""
    p = np.trim_zeros(np.asarray(p, dtype=float), "b")
    if p.size <= 1:
        return True
    return bool(np.all(np.abs(np.roots(p)) < margin))


def reflect_roots(p: np.ndarray) -> np.ndarray:
    """Mirror roots of the monic ``p(q^-1)`` outside the unit circle to ``1/conj(z)``."""
    p = np.asarray(p, dtype=float)
    if p.size <= 1:
        return p.copy()
    r = np.roots(p)
    out = np.abs(r) >= 1.0
    if not np.any(out):
        return p.copy()
    r[out] = 1.0 / np.conj(r[out])
    q = np.real(np.poly(r))
    return q


def std_of(covariance) -> np.ndarray | None:
    """Standard deviations from a covariance matrix (None when there is none); rounding below zero clipped."""
    if covariance is None:
        return None
    return np.sqrt(np.clip(np.diag(covariance), 0.0, None))


@dataclass
class IDPoly:
    """Discrete-time polynomial model (ARX, ARMAX, OE, BJ and their parents).

    Attributes
    ----------
    A, B, C, D, F : ndarray
        Coefficients in powers of ``q^-1``; see module docstring.
    Ts : float
        Sample time in seconds.
    nk : int
        Input delay in samples (number of leading zeros of ``B``).
    noise_variance : float
        Variance of the innovations ``e`` (in output units squared).
    covariance : ndarray or None, shape (d, d)
        Covariance of the free parameters in the order of :attr:`parameters`.
    structure : str
        ``"arx"``, ``"armax"``, ``"oe"``, ``"bj"`` or ``"poly"`` (informative).
    warnings : list of str
        What is wrong with the estimate (unstable, ``B = 0``, non-finite), also issued as
        :class:`~sysid.SysidWarning` when it was estimated; empty when nothing is.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray = field(default_factory=lambda: _ONE.copy())
    D: np.ndarray = field(default_factory=lambda: _ONE.copy())
    F: np.ndarray = field(default_factory=lambda: _ONE.copy())
    Ts: float = 1.0
    nk: int = 1
    noise_variance: float = 0.0
    covariance: np.ndarray | None = None
    structure: str = "poly"
    nb: int | None = None
    loss: float = float("nan")
    n_samples: int = 0
    report: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    def __post_init__(self):
        self.A = _monic(self.A, "A")
        self.C = _monic(self.C, "C")
        self.D = _monic(self.D, "D")
        self.F = _monic(self.F, "F")
        self.B = coefficients(self.B, "B")
        self.Ts = check_sample_time(self.Ts)
        self.nk = int(self.nk)
        if self.nb is None:
            self.nb = max(self.B.size - self.nk, 0)
        if self.B.size < self.nk + self.nb:
            self.B = np.concatenate([self.B, np.zeros(self.nk + self.nb - self.B.size)])

    # ----------------------------------------------------------------- orders
    @property
    def na(self) -> int:
        return self.A.size - 1

    @property
    def nc(self) -> int:
        return self.C.size - 1

    @property
    def nd(self) -> int:
        return self.D.size - 1

    @property
    def nf(self) -> int:
        return self.F.size - 1

    @property
    def orders(self) -> dict:
        """Orders ``na, nb, nc, nd, nf, nk`` as a dict."""
        return dict(na=self.na, nb=self.nb, nc=self.nc, nd=self.nd, nf=self.nf, nk=self.nk)

    # ------------------------------------------------------------- parameters
    @property
    def parameters(self) -> np.ndarray:
        """Free parameters ``[a_1..a_na, b_nk..b_{nk+nb-1}, c_1.., d_1.., f_1..]``, shape (d,)."""
        return np.concatenate([self.A[1:], self.B[self.nk:self.nk + self.nb],
                               self.C[1:], self.D[1:], self.F[1:]])

    @property
    def n_parameters(self) -> int:
        return self.na + self.nb + self.nc + self.nd + self.nf

    def with_parameters(self, theta) -> "IDPoly":
        """Copy of the model with free parameters replaced by ``theta``."""
        theta = np.asarray(theta, dtype=float)
        o = np.cumsum([0, self.na, self.nb, self.nc, self.nd, self.nf])
        B = np.zeros(self.nk + self.nb)
        B[self.nk:] = theta[o[1]:o[2]]
        return IDPoly(np.r_[1.0, theta[o[0]:o[1]]], B, np.r_[1.0, theta[o[2]:o[3]]],
                      np.r_[1.0, theta[o[3]:o[4]]], np.r_[1.0, theta[o[4]:o[5]]],
                      Ts=self.Ts, nk=self.nk, structure=self.structure, nb=self.nb)

    @property
    def std(self) -> np.ndarray | None:
        """Standard deviations of :attr:`parameters` (None when no covariance)."""
        return std_of(self.covariance)

    def polynomial_std(self) -> dict:
        """Standard deviations laid out like ``A, B, C, D, F`` (zeros for fixed entries)."""
        s = self.std
        if s is None:
            raise SysidError("model has no parameter covariance; estimate it with an estimator.")
        o = np.cumsum([0, self.na, self.nb, self.nc, self.nd, self.nf])
        B = np.zeros(self.B.size)
        B[self.nk:self.nk + self.nb] = s[o[1]:o[2]]
        return dict(A=np.r_[0.0, s[o[0]:o[1]]], B=B, C=np.r_[0.0, s[o[2]:o[3]]],
                    D=np.r_[0.0, s[o[3]:o[4]]], F=np.r_[0.0, s[o[4]:o[5]]])

    # ------------------------------------------------------- transfer functions
    def G(self) -> tuple[np.ndarray, np.ndarray]:
        """Input-to-output transfer ``B/(A F)`` as (num, den) in ``q^-1``."""
        return self.B.copy(), np.convolve(self.A, self.F)

    def H(self) -> tuple[np.ndarray, np.ndarray]:
        """Noise transfer ``C/(A D)`` as (num, den) in ``q^-1``."""
        return self.C.copy(), np.convolve(self.A, self.D)

    def poles(self) -> np.ndarray:
        """Poles of ``G`` in the z-plane."""
        return _roots_qinv(np.convolve(self.A, self.F))

    def zeros(self) -> np.ndarray:
        """Finite zeros of ``G`` in the z-plane (without the delay zeros at the origin)."""
        return _roots_qinv(np.trim_zeros(self.B[self.nk:], "f"))

    def freqresp(self, omega) -> np.ndarray:
        """Frequency response ``G(e^{j omega Ts})`` at ``omega`` in rad/s, shape (len(omega),)."""
        w = np.asarray(omega, dtype=float) * self.Ts
        z1 = np.exp(-1j * w)
        num, den = self.G()
        return np.polyval(num[::-1], z1) / np.polyval(den[::-1], z1)

    def __repr__(self):
        """MATLAB-style display: the equation, each polynomial in ``z^-1``, sample time, status."""
        from ._display import poly_text, status_block
        eq = {"arx": "A(z)y(t) = B(z)u(t) + e(t)", "armax": "A(z)y(t) = B(z)u(t) + C(z)e(t)",
              "oe": "y(t) = [B(z)/F(z)]u(t) + e(t)", "bj": "y(t) = [B(z)/F(z)]u(t) + [C(z)/D(z)]e(t)"}
        title = {"arx": "ARX", "armax": "ARMAX", "oe": "OE", "bj": "BJ"}.get(self.structure, "polynomial")
        lines = [f"Discrete-time {title} model: " +
                 eq.get(self.structure, "A(z)y(t) = [B(z)/F(z)]u(t) + [C(z)/D(z)]e(t)")]
        for n in "ABCDF":
            p = getattr(self, n)
            if n == "B" or p.size > 1 or (n == "A" and self.structure in ("arx", "armax", "poly")):
                lines.append(poly_text(f"{n}(z)", p))
        lines += ["", f"Sample time: {self.Ts:g} seconds", "",
                  f"Parameterization: orders na={self.na} nb={self.nb} nc={self.nc} nd={self.nd} nf={self.nf} "
                  f"nk={self.nk}; {self.n_parameters} free coefficients", ""]
        lines += status_block(self, self.structure.upper())
        if self.noise_variance:
            lines.append(f"Noise variance: {self.noise_variance:.4g}")
        return "\n".join(lines)

    __str__ = __repr__


def _roots_qinv(p: np.ndarray) -> np.ndarray:
    p = np.trim_zeros(np.asarray(p, dtype=float), "b")
    if p.size <= 1:
        return np.zeros(0, dtype=complex)
    return np.roots(p).astype(complex)


def idpoly(A, B, C=None, D=None, F=None, Ts=1.0, noise_variance=0.0) -> IDPoly:
    """Build an :class:`IDPoly` like MATLAB ``idpoly(A, B, C, D, F, NoiseVariance, Ts)``.

    ``nk`` is the number of leading zeros of ``B``.
    """
    B = coefficients(B, "B")
    nz = np.flatnonzero(B)
    nk = int(nz[0]) if nz.size else B.size
    one = np.ones(1)
    return IDPoly(A, B, one if C is None else C, one if D is None else D,
                  one if F is None else F, Ts=Ts, nk=nk, noise_variance=noise_variance,
                  nb=B.size - nk)
