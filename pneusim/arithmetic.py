"""One arithmetic path on every x86-64 machine: OpenBLAS's kernels and NumPy's SIMD loops pinned to one CPU
family's.

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

NumPy has the same choice in its own loops: its ``exp``, ``log``, ``power``, ``expm1``, ``log1p``, ``arctan`` and
``cbrt`` dispatch at import to the widest SIMD code the CPU runs (``X86_V4`` and ``AVX512_ICL`` on an AVX-512
machine, ``X86_V3`` on an AVX2 one), and the AVX-512 loops round other last bits.  A diagnosis answered
differently on an AMD EPYC with AVX-512 than on one without, with the same code and the same BLAS kernels; with
the AVX-512 loops switched off it gave the other machine's answer to the last digit (``docs/decisions/0141``).
:func:`pin_numpy_dispatch` switches them off through ``NPY_DISABLE_CPU_FEATURES``, NumPy's own variable for
this, under the same conditions as the BLAS pin (unset, NumPy not loaded, an x86-64 CPU with AVX2 and fused
multiply-add); :func:`numpy_dispatch` says which loops a process runs.
"""

from __future__ import annotations

import os
import platform
import sys

__all__ = ["PINNED_CORETYPE", "pin_blas_kernels", "pinned_here", "blas_kernels", "pin_numpy_dispatch",
           "numpy_dispatch", "numpy_pinned_here"]

#: the OpenBLAS kernels every x86-64 machine with AVX2 and fused multiply-add runs under pneusim
PINNED_CORETYPE = "Haswell"
#: the CPU flags (``/proc/cpuinfo``) the pinned kernels need
_NEEDED_FLAGS = {"avx2", "fma"}
_pinned_here: str | None = None
_numpy_pinned_here: str | None = None
#: NumPy's dispatch targets above AVX2 with fused multiply-add, by the names of NumPy 2.4 on (x86-64 levels) and
#: of the NumPy before it (feature groups); a name the installed NumPy does not dispatch is skipped with an
#: ImportWarning, which Python does not show by default
_ABOVE_V3 = {"levels": ("X86_V4", "AVX512_ICL", "AVX512_SPR"),
             "groups": ("AVX512F", "AVX512CD", "AVX512_KNL", "AVX512_KNM", "AVX512_SKX", "AVX512_CLX",
                        "AVX512_CNL", "AVX512_ICL", "AVX512_SPR")}


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


def _may_pin(environ, variable: str, machine: str | None, flags: set[str] | None,
             numpy_loaded: bool | None) -> bool:
    """Whether a pin may set ``variable``: unset (a user's choice is kept), NumPy not loaded yet (it reads the
    variables once, when it loads), and an x86-64 CPU with AVX2 and fused multiply-add."""
    if variable in environ:
        return False
    if (("numpy" in sys.modules) if numpy_loaded is None else numpy_loaded):
        return False
    machine = platform.machine() if machine is None else machine
    return (machine.lower() in ("x86_64", "amd64")
            and _NEEDED_FLAGS <= (_cpu_flags() if flags is None else flags))


def pin_blas_kernels(environ=None, machine: str | None = None, flags: set[str] | None = None,
                     numpy_loaded: bool | None = None) -> str | None:
    """Set ``OPENBLAS_CORETYPE`` to :data:`PINNED_CORETYPE` in ``environ`` (default ``os.environ``) where it is
    unset, the machine is x86-64, its CPU has AVX2 and fused multiply-add, and NumPy is not loaded yet.

    Returns the core type set, or None where nothing was set (the arguments other than ``environ`` stand in
    for the machine, for tests)."""
    environ = os.environ if environ is None else environ
    if not _may_pin(environ, "OPENBLAS_CORETYPE", machine, flags, numpy_loaded):
        return None
    environ["OPENBLAS_CORETYPE"] = PINNED_CORETYPE
    if environ is os.environ:
        global _pinned_here
        _pinned_here = PINNED_CORETYPE
    return PINNED_CORETYPE


def _numpy_names(numpy_version: str | None) -> str:
    """"levels" for NumPy 2.4 and later (its x86-64 level names), "groups" before (read without importing)."""
    if numpy_version is None:
        from importlib.metadata import PackageNotFoundError, version

        try:
            numpy_version = version("numpy")
        except PackageNotFoundError:
            return "levels"
    major, minor = (int("".join(c for c in part if c.isdigit()) or 0) for part in numpy_version.split(".")[:2])
    return "levels" if (major, minor) >= (2, 4) else "groups"


def pin_numpy_dispatch(environ=None, machine: str | None = None, flags: set[str] | None = None,
                       numpy_loaded: bool | None = None, numpy_version: str | None = None) -> str | None:
    """Set ``NPY_DISABLE_CPU_FEATURES`` to NumPy's dispatch targets above AVX2 with fused multiply-add in
    ``environ`` (default ``os.environ``), under the conditions of :func:`pin_blas_kernels`, so that NumPy's
    loops are an AVX2 machine's everywhere.

    Returns the value set, or None where nothing was set (the other arguments stand in for the machine and
    the installed NumPy's version, for tests)."""
    environ = os.environ if environ is None else environ
    if not _may_pin(environ, "NPY_DISABLE_CPU_FEATURES", machine, flags, numpy_loaded):
        return None
    value = " ".join(_ABOVE_V3[_numpy_names(numpy_version)])
    environ["NPY_DISABLE_CPU_FEATURES"] = value
    if environ is os.environ:
        global _numpy_pinned_here
        _numpy_pinned_here = value
    return value


def numpy_dispatch() -> list[str]:
    """The SIMD targets above its baseline that this process's NumPy dispatches to, e.g. ``["X86_V3"]``
    (imports NumPy)."""
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:  # NumPy before 2.0
        from numpy.core import _multiarray_umath as umath
    return [name for name in umath.__cpu_dispatch__ if umath.__cpu_features__.get(name)]


def numpy_pinned_here() -> str | None:
    """The ``NPY_DISABLE_CPU_FEATURES`` this process's ``import pneusim`` set (None: it set none)."""
    return _numpy_pinned_here


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
