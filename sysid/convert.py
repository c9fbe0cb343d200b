"""Conversion to and from scipy.signal and python-control LTI objects.

Discrete polynomials in ``q^-1`` (MATLAB layout) become z-domain
numerator/denominator of equal length: ``B(q^-1)/A(q^-1) = (B z^n)/(A z^n)``.
Only the input-output transfer ``G = B/(A F)`` is converted; the noise model
is dropped.  A state-space :class:`~sysid.IDSS` stays in state space
(``scipy.signal.dlti(A, B, C, D)``, ``control.ss``): its transfer function's
polynomials would lose the poles of a high-order ``A``.  Models from scipy/control come back as output-error
:class:`~sysid.polynomial.IDPoly` (``y = B/F u + e``).

Input delays: a discrete model's delay ``nk`` is part of ``B`` (leading zeros)
and is carried exactly.  A continuous-time :class:`~sysid.IDTF` with an input
delay cannot be represented by ``scipy.signal.lti`` or
``control.TransferFunction`` (python-control has no time-delay systems), so
``to_scipy`` / ``to_control`` refuse it unless ``pade_order=N`` asks for an
N-th order Padé approximation of ``exp(-s tau)`` (``control.pade``), or
``discrete=True`` asks for the exact zero-order-hold equivalent at the model's
sample time with the delay as whole samples.
"""
from __future__ import annotations

import numpy as np

from .errors import SysidError
from .polynomial import IDPoly
from .statespace import IDSS

__all__ = ["to_scipy", "to_control", "from_scipy", "from_control"]


def _z_polys(model, pade_order=None, discrete=False):
    from .predict import as_idpoly
    if hasattr(model, "to_lti_continuous") and not discrete:
        num, den, ts = model.to_lti_continuous()
        tau = float(model.iodelay)
        if tau > 0:
            if pade_order is None:
                raise SysidError(
                    f"model has an input delay of {tau:g} s, which a delay-free transfer function cannot carry: "
                    f"pass pade_order=N for an N-th order Pade approximation of exp(-{tau:g} s), or discrete=True "
                    f"for the exact sampled form (delay as {model.delay_samples} samples of {model.Ts:g} s).")
            if isinstance(pade_order, bool) or not isinstance(pade_order, (int, np.integer)) or pade_order < 1:
                raise SysidError(f"pade_order must be an integer >= 1, got {pade_order!r}.")
            from control import pade
            pn, pd = pade(tau, int(pade_order))
            num, den = np.polymul(num, pn), np.polymul(den, pd)
        return num, den, ts
    m = as_idpoly(model)
    num, den = m.G()
    n = max(num.size, den.size)
    num = np.r_[num, np.zeros(n - num.size)]
    den = np.r_[den, np.zeros(n - den.size)]
    return num, den, m.Ts


def to_scipy(model, pade_order=None, discrete=False):
    """``scipy.signal.dlti`` (or ``lti`` for continuous-time IDTF) of the input-output transfer.

    A transfer function for IDPoly and IDTF, state space ``(A, B, C, D)`` for IDSS.

    Parameters
    ----------
    model : IDPoly, IDSS or IDTF
    pade_order : int or None
        For an IDTF with an input delay: order of the Padé approximation of the delay
        (required then, see the module docstring); ignored otherwise.
    discrete : bool
        For an IDTF: return the exact ZOH ``dlti`` at ``model.Ts`` (delay in whole samples).
    """
    from scipy import signal
    if isinstance(model, IDSS):
        return signal.dlti(model.A, model.B, model.C, model.D, dt=model.Ts)
    num, den, ts = _z_polys(model, pade_order, discrete)
    if ts == 0:
        return signal.lti(num, den)
    return signal.dlti(np.trim_zeros(num, "f") if np.any(num) else [0.0], den, dt=ts)


def to_control(model, pade_order=None, discrete=False):
    """``control.TransferFunction`` of the input-output transfer (``dt = Ts``, or 0); ``control.ss`` for IDSS.

    ``pade_order`` and ``discrete`` as in :func:`to_scipy` (python-control has no delays).
    """
    import control
    if isinstance(model, IDSS):
        return control.ss(model.A, model.B, model.C, model.D, model.Ts)
    num, den, ts = _z_polys(model, pade_order, discrete)
    return control.tf(num, den, ts)


def _from_z(num, den, ts):
    num = np.atleast_1d(np.asarray(num, dtype=float)).ravel()
    den = np.atleast_1d(np.asarray(den, dtype=float)).ravel()
    num = np.trim_zeros(num, "f") if np.any(num) else np.zeros(1)
    den = np.trim_zeros(den, "f")
    if den.size == 0 or num.size > den.size:
        raise SysidError("system must be proper (numerator degree <= denominator degree).")
    if not (ts and ts > 0):
        raise SysidError(f"system must be discrete-time with a positive sample time, got dt = {ts!r}.")
    B = np.r_[np.zeros(den.size - num.size), num] / den[0]
    F = np.trim_zeros(den / den[0], "b")  # trailing q^-1 zeros carry no information
    nz = np.flatnonzero(B)
    nk = int(nz[0]) if nz.size else 0
    B = B[:nz[-1] + 1] if nz.size else B[:1]
    return IDPoly([1.0], B, F=F, Ts=float(ts), nk=nk, nb=B.size - nk, structure="oe")


def from_scipy(sys) -> IDPoly:
    """Output-error :class:`IDPoly` from a discrete ``scipy.signal`` system."""
    tf = sys.to_tf() if hasattr(sys, "to_tf") else sys
    return _from_z(tf.num, tf.den, getattr(tf, "dt", None))


def from_control(sys) -> IDPoly:
    """Output-error :class:`IDPoly` from a discrete SISO ``control`` system."""
    import control
    tf = control.tf(sys)
    return _from_z(tf.num[0][0], tf.den[0][0], tf.dt)
