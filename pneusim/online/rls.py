"""Online estimators: identification inside the loop, sample by sample, as the mixed-reality paper did.

:class:`PaperRLS` is the recursive least squares of paper 1, equation 8, on the
ARMA structure of its equations 3-6::

    psi(k)  = [-y(k-1) ... -y(k-n), u(k-1) ... u(k-n)]          (eq. 6)
    yhat(k) = psi(k)' theta(k-1)                                  (eq. 5)
    theta(k) = theta(k-1) + P psi (y(k) - yhat(k)) / (lambda + psi' P psi)
    P(k)    = (P - P psi psi' P / (lambda + psi' P psi)) / lambda  (eq. 8)

with ``P(0) = c I`` and ``theta(0) = 0``.  ``theta`` is ``[a1..an, b1..bn]``.

The sample loop (:func:`pneusim.loop.run_loop`) lets each estimator predict and take the new
measurement (:meth:`PaperRLS.update`), then the controller act, then gives it the applied input
(:meth:`PaperRLS.add_input`): the estimators run on exactly the data the loop produces, never on a
stored record.  A ``h``-step prediction ``yhat(k | k-h)`` uses ``theta(k-h)``, the measured outputs
up to ``k-h`` and the applied inputs up to ``k-1``.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import PneusimError
from ..tomlcheck import fail

__all__ = ["PaperRLS", "SysidRLS", "make_rls", "check_rls_settings"]


class PaperRLS:
    """Recursive ARMA estimator of paper 1 (eq. 8) with h-step predictions.

    The recursion and the predictions run in C (:class:`pneusim.online._rls.RlsKernel`,
    about a microsecond per sample at order 5, so that three orders fit a 1 ms loop);
    the arithmetic is eq. 8 as written in the module docstring, dot products summed left to
    right.  (numpy's BLAS sums in another order; on paper 1's loop data RLS amplifies that last
    bit to ~1e-10 of theta, as much as a one-ulp change of the data does.)

    Parameters
    ----------
    order : int
        ``n = na = nb``.
    forgetting : float
        Forgetting factor lambda in (0, 1].
    initial_covariance : float
        ``c`` of ``P(0) = c I``.
    horizons : sequence of int
        Prediction steps to produce at every sample (1 = one-step prediction).

    Attributes
    ----------
    theta : ndarray (2n,)
        ``[a1..an, b1..bn]`` after the last sample (a new array at every access).
    P : ndarray (2n, 2n)
        The covariance after the last sample (a new array at every access).
    k : int
        Outputs taken so far.
    """

    engine = "pneusim PaperRLS"

    def __init__(self, order: int, forgetting: float = 0.99, initial_covariance: float = 1000.0,
                 horizons: Sequence[int] = (1,)):
        try:
            from ._rls import RlsKernel   # compiled: a source tree whose extensions were not built lacks it
        except ImportError:
            raise PneusimError("the compiled RLS (pneusim/online/_rls.pyx) is not built; build it with: "
                               "pip install --no-build-isolation -e .") from None

        self.order, self.forgetting, self.c = int(order), float(forgetting), float(initial_covariance)
        self.horizons = tuple(int(h) for h in horizons)
        self._kernel = RlsKernel(self.order, self.forgetting, self.c, self.horizons)

    @property
    def theta(self) -> np.ndarray:
        return self._kernel.theta_copy()

    @property
    def P(self) -> np.ndarray:
        return self._kernel.P_copy()

    @property
    def k(self) -> int:
        return self._kernel.k

    def theta_logger(self, log: np.ndarray):
        """``log_theta(k)`` writing ``theta`` into row ``k`` of ``log`` (float64, C-contiguous, (N, 2n))
        without allocating: how the real-time loop keeps the coefficient traces."""
        self._kernel.set_theta_log(log)
        return self._kernel.log_theta

    def update(self, y: float) -> dict[int, float]:
        """Take the measurement ``y(k)``; return ``{h: yhat(k | k-h)}`` (NaN until enough history)."""
        return dict(zip(self.horizons, self._kernel.update(y)))

    def add_input(self, u: float) -> None:
        """Record the input ``u(k)`` applied after the measurement ``y(k)``."""
        self._kernel.add_input(u)

    def predictions(self) -> dict[int, float]:
        """``yhat(k | k-h)`` for every horizon, before ``y(k)`` is taken (inputs up to ``k-1`` known).

        ``yhat(k | k-h)`` iterates the model of ``theta(k-h)`` h times from the measured outputs up
        to ``k-h``, on the applied inputs up to ``k-1``.
        """
        return dict(zip(self.horizons, self._kernel.predictions()))


class SysidRLS(PaperRLS):
    """:class:`PaperRLS` whose recursion is :class:`sysid.RecursiveARX` ``([n, n, 1])`` (same eq. 8).

    ``sysid`` takes ``(y(k), u(k))`` together, so the update on ``y(k)`` is
    completed in :meth:`add_input`, once the controller has chosen ``u(k)``;
    the prediction made before ``y(k)`` is taken is unchanged.  (``P`` stays ``c I`` here:
    the covariance lives in the sysid estimator.)
    """

    engine = "sysid.RecursiveARX"

    def __init__(self, order, forgetting=0.99, initial_covariance=1000.0, horizons=(1,)):
        import sysid   # sysid imports SciPy's signal module (about a second): only this engine needs it

        super().__init__(order, forgetting, initial_covariance, horizons)
        self._est = sysid.RecursiveARX([self.order, self.order, 1], forgetting=self.forgetting,
                                       initial_covariance=self.c)
        self._pending_y = 0.0

    def update(self, y: float) -> dict[int, float]:
        self._pending_y = float(y)
        return dict(zip(self.horizons, self._kernel.take_output(y)))

    def add_input(self, u: float) -> None:
        self._est.update(self._pending_y, float(u))
        self._kernel.set_theta(self._est.parameters)
        self._kernel.add_input(u)


def make_rls(order, forgetting, initial_covariance, horizons, engine: str = "auto") -> PaperRLS:
    """The in-loop estimator: ``sysid`` (its RecursiveARX), ``pneusim`` (:class:`PaperRLS`) or
    ``auto`` (sysid when it has RecursiveARX, else pneusim)."""
    if engine in ("auto", "sysid"):
        try:
            import sysid   # about a second (SciPy's signal module): only the sysid engine needs it

            if hasattr(sysid, "RecursiveARX"):
                return SysidRLS(order, forgetting, initial_covariance, horizons)
        except ImportError:
            pass
        if engine == "sysid":
            raise PneusimError("engine = 'sysid' needs sysid.RecursiveARX, which is not available")
    return PaperRLS(order, forgetting, initial_covariance, horizons)


def check_rls_settings(where, prefix: str, ident: dict, n_samples: int, max_abs_y: float,
                       max_abs_u: float | None) -> None:
    """One online (``rls``) identifier's settings of a scenario or MRE file against its run.

    Its horizons must be shorter than the run's ``n_samples`` samples (no prediction farther ahead could be
    scored), and its forgetting factor and initial covariance must give an estimate on signals up to
    ``max_abs_y`` and ``max_abs_u`` (identifier units; None: not bounded) -- :func:`sysid.check_rls_options`,
    the checks of :class:`sysid.RecursiveARX`, the same recursion (``forgetting = 1e-300`` or
    ``initial_covariance = 1e308`` give none).  A fault raises the one-line error naming ``where`` and the
    field under ``prefix`` (e.g. ``identifiers[0].forgetting``).
    """
    import sysid   # about a second (SciPy's signal module); a file with identifiers imports it to run them anyway

    too_long = [h for h in ident["horizons"] if h >= n_samples]
    if too_long:
        fail(where, f"{prefix}.horizons", f"expected horizons shorter than the run's {n_samples} samples, got "
                                          f"{too_long[0]} (no prediction that far ahead would be scored)")
    try:
        sysid.check_rls_options([ident["order"], ident["order"], 1], ident["forgetting"], ident["initial_covariance"],
                                max_abs_y=max_abs_y, max_abs_u=max_abs_u)
    except sysid.SysidError as exc:
        text = str(exc)
        key = next((k for k in ("forgetting", "initial_covariance") if text.startswith(k)), None)
        fail(where, f"{prefix}.{key}" if key else prefix, text.rstrip("."))
