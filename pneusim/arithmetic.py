"""One arithmetic path on every x86-64 machine: OpenBLAS's kernels pinned to one CPU family's.

OpenBLAS picks its kernels for the CPU it finds (``SkylakeX`` on an AVX-512 Xeon, ``Haswell`` on an AMD EPYC),
and each sums in another order, so a product's last bits depend on the machine.  A fit that ends where the model
lacks physics (parameters at their bounds, a penalty formulation) amplifies those bits: the nominal fit of a
three-effect recording ended between -18.5 % and -33.5 % of validation fit under four kernels, and the diagnosis
that followed named other effects (``docs/decisions/0133``).  As Intel MKL's conditional numerical reproducibility (``MKL_CBWR``) does, pneusim
asks OpenBLAS for the same kernels everywhere they run: ``OPENBLAS_CORETYPE=Haswell`` (AVX2 with fused
multiply-add: Intel Core and Xeon CPUs since 2013, every AMD Zen) where the variable is unset.

OpenBLAS reads the variable once, when NumPy loads it, so :func:`pin_blas_kernels` runs first thing in
``import pneusim`` and does nothing once NumPy is imported (a process that imported NumPy first keeps its CPU's
kernels, and its worker processes must not get others).  A variable the user set is kept: that is how the tests
run again on a second path.  :func:`blas_kernels` says which kernels a process runs.
"""

from __future__ import annotations

import os
import platform
import sys

__all__ = ["PINNED_CORETYPE", "pin_blas_kernels", "pinned_here", "blas_kernels"]

#: the OpenBLAS kernels every x86-64 machine with AVX2 and fused multiply-add runs under pneusim
PINNED_CORETYPE = "Haswell"
#: the CPU flags (``/proc/cpuinfo``) the pinned kernels need
_NEEDED_FLAGS = {"avx2", "fma"}
_pinned_here: str | None = None


def _cpu_flags(cpuinfo: str = "/proc/cpuinfo") -> set[str]:
    """The first processor's flags from ``cpuinfo`` (Linux); empty where it cannot be read."""
    try:
        with open(cpuinfo, encoding="ascii", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "flags":
                    return set(value.split())
    except OSError:
        pass
    return set()


def pin_blas_kernels(environ=None, machine: str | None = None, flags: set[str] | None = None,
                     numpy_loaded: bool | None = None) -> str | None:
    """Set ``OPENBLAS_CORETYPE`` to :data:`PINNED_CORETYPE` in ``environ`` (default ``os.environ``) where it is
    unset, the machine is x86-64, its CPU has AVX2 and fused multiply-add, and NumPy is not loaded yet.

    Returns the core type set, or None where nothing was set (the arguments other than ``environ`` stand in
    for the machine, for tests)."""
    environ = os.environ if environ is None else environ
    if "OPENBLAS_CORETYPE" in environ:
        return None
    if (("numpy" in sys.modules) if numpy_loaded is None else numpy_loaded):
        return None
    machine = platform.machine() if machine is None else machine
    if machine.lower() not in ("x86_64", "amd64"):
        return None
    if not _NEEDED_FLAGS <= (_cpu_flags() if flags is None else flags):
        return None
    environ["OPENBLAS_CORETYPE"] = PINNED_CORETYPE
    if environ is os.environ:
        global _pinned_here
        _pinned_here = PINNED_CORETYPE
    return PINNED_CORETYPE


def pinned_here() -> str | None:
    """The core type this process's ``import pneusim`` set (None: it set none; the variable, if set, is the
    user's or a parent process's)."""
    return _pinned_here


def blas_kernels() -> list[str]:
    """The kernels (OpenBLAS's ``architecture``) of every BLAS library this process has loaded, e.g.
    ``["Haswell", "Haswell"]`` for NumPy's and SciPy's; imports NumPy and SciPy's linear algebra to load them."""
    import numpy  # noqa: F401 - loads NumPy's BLAS
    import scipy.linalg  # noqa: F401 - loads SciPy's
    from threadpoolctl import threadpool_info

    return [str(info.get("architecture") or info.get("internal_api")) for info in threadpool_info()
            if info.get("user_api") == "blas"]
