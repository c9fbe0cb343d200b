"""Online identification inside the loop, sample by sample, as the mixed-reality paper did.

:class:`PaperRLS` is the recursive least squares of paper 1, equation 8, on the
ARMA structure of its equations 3-6::

    psi(k)  = [-y(k-1) ... -y(k-n), u(k-1) ... u(k-n)]          (eq. 6)
    yhat(k) = psi(k)' theta(k-1)                                  (eq. 5)
    theta(k) = theta(k-1) + P psi (y(k) - yhat(k)) / (lambda + psi' P psi)
    P(k)    = (P - P psi psi' P / (lambda + psi' P psi)) / lambda  (eq. 8)

with ``P(0) = c I`` and ``theta(0) = 0``.  ``theta`` is ``[a1..an, b1..bn]``.

:func:`simulate_online` steps a :class:`~pneusim.plant.SimulatedPlant` and, at
every sample, first lets each estimator predict and update on the new
measurement, then lets the controller act: the estimators run inside the loop
on exactly the data the loop produces, never on a stored record.  A ``h``-step
prediction ``yhat(k | k-h)`` uses ``theta(k-h)``, the measured outputs up to
``k-h`` and the applied inputs up to ``k-1``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from .. import __version__
from ..experiment import Experiment
from ..plant import SimulatedPlant
from ..recording import Recording
from ..rig import Rig

__all__ = ["PaperRLS", "SysidRLS", "make_rls", "simulate_online", "OnlineResult"]


class PaperRLS:
    """Recursive ARMA estimator of paper 1 (eq. 8) with h-step predictions.

    The recursion and the predictions run in C (:class:`pneusim.scenario._rls.RlsKernel`,
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
            from ._rls import RlsKernel
        except ImportError:        # a source tree whose extensions were not built
            from ..errors import PneusimError
            raise PneusimError("the compiled RLS (pneusim/scenario/_rls.pyx) is not built; build it with: "
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
        import sysid

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
            import sysid

            if hasattr(sysid, "RecursiveARX"):
                return SysidRLS(order, forgetting, initial_covariance, horizons)
        except ImportError:
            pass
        if engine == "sysid":
            from ..errors import PneusimError
            raise PneusimError("engine = 'sysid' needs sysid.RecursiveARX, which is not available")
    return PaperRLS(order, forgetting, initial_covariance, horizons)


@dataclass
class OnlineResult:
    """What :func:`simulate_online` returns.

    Attributes
    ----------
    recording : Recording
    predictions : dict
        ``{(estimator name, h): ndarray (N,)}``, output units, NaN where undefined.
    thetas : dict
        ``{estimator name: ndarray (N, 2n)}``, theta after each sample.
    wall_time_s : float
    """

    recording: Recording
    predictions: dict = field(default_factory=dict)
    thetas: dict = field(default_factory=dict)
    wall_time_s: float = 0.0


def simulate_online(rig: Rig, experiment: Experiment, estimators: dict[str, PaperRLS],
                    to_output: Callable[[float], float], to_input: Callable[[float, int], float],
                    effects=(), *, seed: int = 0, noise_scale: float = 1.0, progress: bool = False) -> OnlineResult:
    """Run ``experiment`` with the estimators inside the loop.

    Parameters
    ----------
    estimators : {name: PaperRLS}
    to_output : callable(position_m) -> y
        Measured position (m) to the estimators' output unit.
    to_input : callable(command_V, k) -> u
        Applied command (V) and sample index to the estimators' input.
    """
    if experiment.sample_time_s != rig.sample_time_s:
        rig = rig.with_params({"sample_time_s": experiment.sample_time_s})
    from ..mre.loop import StatusLine, run_loop

    plant = SimulatedPlant(rig, effects, seed=seed, noise_scale=noise_scale)
    ts, n, closed = experiment.sample_time_s, experiment.n_samples, experiment.loop == "closed"
    ctrl = experiment.controller
    first = experiment.signal[0]
    x0 = experiment.initial_position_m
    if x0 is None:
        x0 = float(np.clip(first, 0.0, rig.stroke_m)) if closed else 0.5 * rig.stroke_m
    n_warm = int(round(experiment.warmup_s / ts))
    plant.reset(x0, ctrl.command(-n_warm * ts, first, x0) if closed else first, t0_s=-n_warm * ts)
    # the one sample loop of pneusim.mre, here as fast as possible (no pacing)
    res = run_loop(plant, experiment.signal, ctrl if closed else None, estimators, to_output, to_input,
                   n_warm=n_warm, status=StatusLine(interval_s=0.5, label="online run") if progress else None)
    if not res.completed:
        if res.stop_reason.startswith("interrupted"):
            raise KeyboardInterrupt
        raise res.exception
    pos, cmd, pa, pb = res.position_m, res.valve_cmd_V, res.pressure_a_Pa, res.pressure_b_Pa
    preds, thetas, wall = res.predictions, res.thetas, res.wall_time_s
    meta = {"format": "pneusim-recording/1", "sample_time_s": repr(ts), "rig": rig.name, "loop": experiment.loop,
            "description": experiment.description or "online identification run",
            "generator": f"pneusim {__version__}", "seed": str(seed),
            "effects": ";".join(repr(e) for e in plant.model.effects) or "none"}
    if closed:
        meta.update(ctrl.metadata())
    rec = Recording(time_s=np.arange(n) * ts, valve_cmd_V=cmd, position_m=pos,
                    reference_m=experiment.signal.copy() if closed else None,
                    pressure_a_Pa=pa, pressure_b_Pa=pb, metadata=meta)
    return OnlineResult(rec, preds, thetas, wall)
