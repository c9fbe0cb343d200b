"""Responses of an innovations state-space model computed in state space (internal to :mod:`sysid`).

:func:`sysid.simulate`, :func:`sysid.predict` and :func:`sysid.compare` evaluate an
:class:`~sysid.IDSS` here rather than through its polynomial form: the characteristic
polynomial of ``A`` (``to_idpoly``) loses the poles of a high-order model (a 100-state
n4sid model whose ``A`` has ``max |eig| = 0.9998`` becomes a polynomial with a root at
``|z| = 3.2``, whose simulation overflows), while a unitary change of basis keeps them.

Every response is a state sequence of ``x(t+1) = F x(t) + w(t)`` (:func:`state_sequence`),
solved through the complex Schur form ``F = Z T Z^H``: ``Z`` is unitary, so the eigenvalues
stay on the diagonal of ``T`` as accurately as ``eig(F)`` gives them, and ``z = Z^H x`` obeys
an upper-triangular recursion, solved from the last component up as first-order filters
(``scipy.signal.lfilter``), each driven by its input and the components below it:
``O(N n^2)`` operations, no Python loop over samples.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import schur
from scipy.signal import lfilter

__all__ = ["state_sequence", "simulate_states", "free_response_rows", "predict_states"]


def state_sequence(F: np.ndarray, W: np.ndarray, x0=None) -> np.ndarray:
    """States ``x(0) .. x(N-1)`` of ``x(t+1) = F x(t) + w(t)``, ``x(0) = x0``.

    Parameters
    ----------
    F : ndarray, shape (n, n)
        Real state matrix.
    W : ndarray, shape (N, n)
        Row ``t`` is ``w(t)``.
    x0 : ndarray, shape (n,), optional
        Initial state (zeros by default).

    Returns
    -------
    ndarray, shape (N, n)
        Row ``t`` is ``x(t)``.  Grows without bound (to inf) when ``F`` is unstable.
    """
    N, n = W.shape
    T, Z = schur(F, output="complex")
    V = W @ Z.conj()                      # row t: (Z^H w(t))^T
    z0 = np.zeros(n, complex) if x0 is None else Z.conj().T @ np.asarray(x0, float)
    S = np.empty((N, n), complex)
    for i in range(n - 1, -1, -1):
        drive = V[:, i] if i == n - 1 else V[:, i] + S[:, i + 1:] @ T[i, i + 1:]
        # z_i(t+1) = T_ii z_i(t) + drive(t), z_i(0) = z0_i
        S[:, i] = lfilter([0.0, 1.0], [1.0, -T[i, i]], drive, zi=z0[i:i + 1])[0]
    return (S @ Z.T).real                 # row t: (Z z(t))^T


def simulate_states(A, B, C, D, u) -> np.ndarray:
    """Output ``y(t) = C x(t) + D u(t)`` of ``x(t+1) = A x(t) + B u(t)`` from ``x(0) = 0``, shape (N,)."""
    X = state_sequence(A, u[:, None] * B.ravel()[None, :])
    return X @ C.ravel() + D.item() * u


def free_response_rows(A, C, N: int) -> np.ndarray:
    """Rows ``C A^t``, ``t = 0 .. N-1``, shape (N, n): the output of ``x(0) = e_j`` in column ``j``."""
    n = A.shape[0]
    return state_sequence(A.T, np.zeros((N, n)), x0=C.ravel())


def predict_states(A, B, C, D, K, y, u, k: int) -> np.ndarray:
    """k-step-ahead prediction ``y_hat(t | t-k)`` of the innovations model, zero initial state, shape (N,).

    The one-step predictor ``x_hat(t+1) = (A - K C) x_hat(t) + (B - K D) u(t) + K y(t)`` gives
    ``x_hat(s | s-1)``; from there ``k - 1`` steps without new outputs::

        x_hat(t | t-k) = x_s(t) + A^(k-1) (x_hat(s | s-1) - x_s(s)),  s = t - k + 1,

    with ``x_s`` the simulated state (zero initial state; both follow ``A`` and ``B u``
    over those steps), and ``y_hat = C x_hat(t | t-k) + D u(t)``.
    """
    c, d = C.ravel(), D.item()
    Ab = A - K @ C
    Xh = state_sequence(Ab, u[:, None] * (B - K * d).ravel()[None, :] + y[:, None] * K.ravel()[None, :])
    if k == 1:
        return Xh @ c + d * u
    Xs = state_sequence(A, u[:, None] * B.ravel()[None, :])
    yhat = Xs @ c + d * u
    N = y.size
    g = c @ np.linalg.matrix_power(A, k - 1)           # C A^(k-1)
    yhat[k - 1:] += (Xh[:N - k + 1] - Xs[:N - k + 1]) @ g
    return yhat
