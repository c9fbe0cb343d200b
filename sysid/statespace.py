"""Discrete-time innovations state-space model (MATLAB ``idss``).

``x(t+1) = A x(t) + B u(t) + K e(t)``,  ``y(t) = C x(t) + D u(t) + e(t)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import ss2tf

from .polynomial import IDPoly

__all__ = ["IDSS"]


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
        Variance of ``e``.
    singular_values : ndarray or None
        Singular values used to choose the order (subspace estimation).
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
                      noise_variance=self.noise_variance, structure="armax")

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` (z-plane)."""
        return np.linalg.eigvals(self.A)

    def zeros(self) -> np.ndarray:
        """Zeros of the input-output transfer function (z-plane)."""
        return self.to_idpoly().zeros()

    def freqresp(self, omega) -> np.ndarray:
        """``G(e^{j omega Ts})`` at ``omega`` in rad/s."""
        return self.to_idpoly().freqresp(omega)
