"""Discrete-time innovations state-space model (MATLAB ``idss``).

``x(t+1) = A x(t) + B u(t) + K e(t)``,  ``y(t) = C x(t) + D u(t) + e(t)``.

A state-space realisation is defined only up to a change of state basis, so
the parameters that carry an uncertainty are those of the equivalent ARMAX
form ``det(qI - A) y = B(q) u + C(q) e`` (:meth:`IDSS.to_idpoly`), which do
not depend on the basis: :attr:`IDSS.parameters` and :attr:`IDSS.covariance`
refer to them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import ss2tf

from .data import check_sample_time
from .errors import SysidError
from .polynomial import IDPoly, std_of

__all__ = ["IDSS", "idss_from_armax"]


@dataclass
class IDSS:
    """Innovations-form state-space model.

    Attributes
    ----------
    A : ndarray, shape (nx, nx)
    B : ndarray, shape (nx, 1)
    C : ndarray, shape (1, nx)
    D : ndarray, shape (1, 1)
    K : ndarray, shape (nx, 1)
        Kalman (innovations) gain.
    Ts : float
        Sample time in seconds.
    noise_variance : float
        Variance of ``e`` (output units squared).
    singular_values : ndarray or None
        Singular values used to choose the order (subspace estimation).
    covariance : ndarray or None, shape (d, d)
        Covariance of :attr:`parameters` (the ARMAX-equivalent coefficients).
    loss : float
        Mean squared one-step prediction error on the estimation data.
    n_samples : int
        Number of estimation samples.
    warnings : list of str
        What is wrong with the estimate (unstable, ``B = 0``, non-finite), also issued as
        :class:`~sysid.SysidWarning` when it was estimated; empty when nothing is.
    report : dict
        Estimation details: ``fit_percent`` (fit to the estimation data, MATLAB's display),
        ``focus``, ``method``, ``x0`` (estimated initial state, n4sid) ...
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    K: np.ndarray
    Ts: float = 1.0
    noise_variance: float = 0.0
    singular_values: np.ndarray | None = None
    report: dict = field(default_factory=dict)
    covariance: np.ndarray | None = None
    loss: float = float("nan")
    n_samples: int = 0
    warnings: list = field(default_factory=list)

    def __post_init__(self):
        A = _real_matrix(self.A, "A")
        n = A.shape[0]
        if A.shape != (n, n) or n == 0:
            raise SysidError(f"A must be a square matrix with at least one state, got shape {A.shape}.")
        shapes = {"B": (n, 1), "C": (1, n), "D": (1, 1), "K": (n, 1)}
        for name, shape in shapes.items():
            M = _real_matrix(getattr(self, name), name)
            if M.size != shape[0] * shape[1] or (M.shape != shape and min(M.shape) != 1):
                raise SysidError(f"{name} must have shape {shape} for a model with {n} states "
                                 f"(one input, one output), got {M.shape}.")
            setattr(self, name, M.reshape(shape))
        self.A = A
        self.Ts = check_sample_time(self.Ts)

    @property
    def nx(self) -> int:
        """State dimension."""
        return self.A.shape[0]

    def to_idpoly(self) -> IDPoly:
        """Equivalent ARMAX form ``det(qI-A) y = num_G u + num_H e`` (same transfer functions)."""
        den, = ss2tf(self.A, self.B, self.C, self.D)[1:]
        numG = ss2tf(self.A, self.B, self.C, self.D)[0].ravel()
        numH = ss2tf(self.A, self.K, self.C, np.ones((1, 1)))[0].ravel()
        if self.D.item() == 0.0:
            numG[0] = 0.0
        nk = 0 if numG[0] != 0.0 else 1
        numH = numH / numH[0]
        return IDPoly(den, numG, numH, Ts=self.Ts, nk=nk, nb=numG.size - nk,
                      noise_variance=self.noise_variance, structure="armax", covariance=self.covariance)

    @property
    def parameters(self) -> np.ndarray:
        """Basis-independent parameters ``[a_1..a_nx, b_nk.., c_1..c_nx]`` of :meth:`to_idpoly`, shape (d,)."""
        return self.to_idpoly().parameters

    @property
    def n_parameters(self) -> int:
        """Number of identifiable parameters, ``3 nx`` (+1 with feedthrough)."""
        return self.to_idpoly().n_parameters

    @property
    def std(self) -> np.ndarray | None:
        """Standard deviations of :attr:`parameters` (None when no covariance)."""
        return std_of(self.covariance)

    def __repr__(self) -> str:
        """MATLAB-style display: equations, matrices (large ones summarised), sample time, status."""
        from ._display import matrix_block, status_block
        lines = ["Discrete-time identified state-space model:",
                 "    x(t+Ts) = A x(t) + B u(t) + K e(t)",
                 "       y(t) = C x(t) + D u(t) + e(t)", ""]
        for name, M, r, c in (("A", self.A, "x", "x"), ("B", self.B, "x", "u"), ("C", self.C, "y", "x"),
                              ("D", self.D, "y", "u"), ("K", self.K, "x", "y")):
            lines += matrix_block(name, M, r, c)
        lines += ["", f"Sample time: {self.Ts:g} seconds", "", "Parameterization:",
                  f"   FREE form (all coefficients in A, B, C, K free), {self.nx} states.",
                  f"   Feedthrough: {'yes' if np.any(self.D) else 'none'}",
                  f"   Number of basis-independent parameters (ARMAX form): {self.n_parameters}", ""]
        rep = self.report or {}
        how = "N4SID" if rep.get("method") == "n4sid" else ("SSEST" if "iterations" in rep else "a sysid estimator")
        if rep.get("weighting"):
            how += f" (weighting {rep['weighting'].upper()}, horizon {rep.get('horizon', '?')}"
            how += ", stability enforced)" if rep.get("stability_enforced") else ")"
        lines += status_block(self, how)
        return "\n".join(lines)

    __str__ = __repr__

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` (z-plane)."""
        return np.linalg.eigvals(self.A)

    def zeros(self) -> np.ndarray:
        """Zeros of the input-output transfer function (z-plane)."""
        return self.to_idpoly().zeros()

    def freqresp(self, omega) -> np.ndarray:
        """``G(e^{j omega Ts}) = C (zI - A)^-1 B + D`` at ``omega`` in rad/s (shape of ``omega``).

        Evaluated in state space (one linear solve per frequency), not through the
        characteristic polynomial of ``A``, which loses the poles of a high-order model.
        """
        w = np.asarray(omega, dtype=float)
        z = np.exp(1j * w.ravel() * self.Ts)
        n = self.nx
        M = z[:, None, None] * np.eye(n) - self.A
        x = np.linalg.solve(M, np.broadcast_to(self.B.astype(complex), (z.size, n, 1)))
        return ((self.C @ x)[:, 0, 0] + self.D.item()).reshape(w.shape)


def _real_matrix(M, name: str) -> np.ndarray:
    try:
        a = np.asarray(M)
        a = np.atleast_2d(a.astype(float)) if a.dtype.kind in "biufO" and a.ndim <= 2 else None
    except (TypeError, ValueError):
        a = None
    if a is None:
        raise SysidError(f"{name} must be a real matrix (at most 2-D), got {type(M).__name__} {np.shape(M)}.")
    return a


def idss_from_armax(p: IDPoly, **attributes) -> IDSS:
    """Observer-canonical :class:`IDSS` of an ARMAX model ``A y = B u + C e``.

    With ``n = max(na, nb + nk - 1, nc)`` and coefficients padded with zeros::

        A_ss = [[-a_1, 1, 0 ..], [-a_2, 0, 1 ..], .., [-a_n, 0 .. 0]]
        B_ss = b_{1..n} - a_{1..n} b_0,  D = b_0,  K = c_{1..n} - a_{1..n},  C_ss = [1, 0 .. 0]

    Parameters
    ----------
    p : IDPoly
        Model with ``D = F = 1``.
    **attributes
        Passed to :class:`IDSS` (``noise_variance``, ``covariance``, ...).
    """
    if p.nd or p.nf:
        raise SysidError(f"model must be ARMAX (D = F = 1) for a state-space form, got nd={p.nd}, nf={p.nf}.")
    n = max(p.na, p.B.size - 1, p.nc)
    if n == 0:
        raise SysidError("model must have at least one state (na, nb + nk - 1 or nc >= 1).")

    def pad(x):
        out = np.zeros(n + 1)
        out[:x.size] = x
        return out

    a, b, c = pad(p.A), pad(p.B), pad(p.C)
    A = np.zeros((n, n))
    A[:, 0] = -a[1:]
    A[:-1, 1:] = np.eye(n - 1)
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    return IDSS(A, (b[1:] - a[1:] * b[0]).reshape(n, 1), C, np.array([[b[0]]]),
                (c[1:] - a[1:]).reshape(n, 1), Ts=p.Ts, **attributes)
