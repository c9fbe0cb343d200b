"""pneusim: physics of servo-pneumatic rigs, solved by SUNDIALS, for benchmarking identification."""

__version__ = "0.1.0"


def __getattr__(name):
    # ``pneusim.diagnose(...)`` without importing CasADi at ``import pneusim``
    if name == "diagnose":
        from .diagnosis import diagnose

        return diagnose
    raise AttributeError(f"module 'pneusim' has no attribute {name!r}")
