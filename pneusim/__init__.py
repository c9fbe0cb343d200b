"""pneusim: physics of servo-pneumatic rigs, solved by SUNDIALS, for benchmarking identification."""

from .version import __version__

__all__ = ["__version__", "diagnose"]


def __getattr__(name):
    # ``pneusim.diagnose(...)`` without importing CasADi and SciPy at ``import pneusim`` (seconds)
    if name == "diagnose":
        from .diagnosis import diagnose

        return diagnose
    raise AttributeError(f"module 'pneusim' has no attribute {name!r}")
