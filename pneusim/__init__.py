"""pneusim: physics of servo-pneumatic rigs, solved by SUNDIALS, for benchmarking identification."""

# first, before anything loads NumPy: the same BLAS kernels and NumPy loops on every x86-64 machine (see
# .arithmetic)
from .arithmetic import pin_blas_kernels, pin_numpy_dispatch

pin_blas_kernels()
pin_numpy_dispatch()

from .version import __version__  # noqa: E402 - after the pin

__all__ = ["__version__", "diagnose"]


def __getattr__(name):
    # ``pneusim.diagnose(...)`` without importing CasADi and SciPy at ``import pneusim`` (seconds)
    if name == "diagnose":
        from .diagnosis import diagnose

        return diagnose
    raise AttributeError(f"module 'pneusim' has no attribute {name!r}")
