"""One BLAS thread inside the estimators (internal), through threadpoolctl.

The least-squares problems of :mod:`sysid` are tall and narrow (``N x d`` with
``N`` up to ~1e5 and ``d`` up to ~50): OpenBLAS threads gain nothing on them,
and on a loaded machine their spin-waiting costs 5-20x (a QR of an
8000 x 41 matrix: 7 ms on one thread, 75 ms with two threads competing with
other processes).  Each estimator call therefore runs with the BLAS libraries
limited to one thread and restores the previous setting afterwards, as
scikit-learn does.
"""
from __future__ import annotations

import functools

__all__ = ["one_blas_thread"]

_controller = None


def _blas_limited():
    global _controller
    if _controller is None:
        from threadpoolctl import ThreadpoolController
        _controller = ThreadpoolController()   # finds the loaded BLAS libraries once (~10 ms)
    return _controller.limit(limits=1, user_api="blas")


def one_blas_thread(method):
    """Decorator: run ``method`` with the BLAS libraries limited to one thread."""
    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        with _blas_limited():
            return method(*args, **kwargs)
    return wrapper
