"""One BLAS thread while the fit runs (internal), through threadpoolctl.

The fit's heavy work is CVODES integrating segments in :class:`~.shooting.ShootingProblem`'s own
threads (one per core); the linear algebra between integrations is small (sparse products, LSMR,
IPOPT's sparse factorisation).  OpenBLAS's worker threads spin-wait after every call and take cores
from the integrating threads when the machine is busy: the paper-2 benchmark fit took 41.5 s with
OpenBLAS's two threads and 27.1 s with one, side by side with two diagnoses on this 2-core machine
(pre-fit 22.9 -> 15.2 s for the same 35 evaluations); on the idle machine the pre-fit took 8.5 and
8.0 s.  As scikit-learn and :mod:`sysid` do, the limit holds for the call and the previous setting
comes back afterwards.
"""
from __future__ import annotations

import functools

__all__ = ["one_blas_thread"]

_controller = None


def one_blas_thread(function):
    """Decorator: run ``function`` with the BLAS libraries limited to one thread."""
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        global _controller
        if _controller is None:
            from threadpoolctl import ThreadpoolController
            _controller = ThreadpoolController()   # finds the loaded BLAS libraries once (~10 ms)
        with _controller.limit(limits=1, user_api="blas"):
            return function(*args, **kwargs)
    return wrapper
