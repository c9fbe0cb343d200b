"""CasADi functions to compiled C, called without Python in between.

CasADi generates C for the model's right-hand side and Jacobian; gcc compiles
it into a shared library kept in a cache (``$PNEUSIM_CACHE`` or
``~/.cache/pneusim``), keyed by a hash of the source, so each model structure is
compiled once per machine.  The library's function addresses are handed to the
Cython callbacks of :mod:`pneusim.solver._cvode_compiled`.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import casadi as ca

from ..errors import PneusimError

__all__ = ["CompiledFunction", "compile_functions", "cache_dir"]

_LOADED: dict[str, ctypes.CDLL] = {}
#: -O2 inlines CasADi's small helpers (casadi_sq, casadi_fmax, ...) into the kernels; -fno-math-errno
#: lets sqrt be one instruction.  Neither changes a result (no -ffast-math).  Part of the cache key.
_CFLAGS = ("-O2", "-fno-math-errno", "-fno-semantic-interposition")


def cache_dir() -> Path:
    root = os.environ.get("PNEUSIM_CACHE") or Path.home() / ".cache" / "pneusim"
    path = Path(root)
    path.mkdir(parents=True, exist_ok=True)
    return path


@dataclass(frozen=True)
class CompiledFunction:
    """Address and work-array sizes of one compiled CasADi function."""

    name: str
    address: int
    n_iw: int
    n_w: int
    library: ctypes.CDLL
    n_arg: int = 3   #: length of the argument pointer array the function needs
    n_res: int = 1


def compile_functions(functions: list[ca.Function], prefix: str = "pneusim",
                      max_args: int | None = 3) -> dict[str, CompiledFunction]:
    """Generate, compile (once, cached) and load ``functions``; keys are the functions' names.

    ``max_args``: the callers' argument arrays hold this many pointers (the
    CVODE kernels pass ``(x, u, p)``); ``None`` for callers that size them from
    :attr:`CompiledFunction.n_arg`.
    """
    for f in functions:
        if max_args is not None and (f.sz_arg() > max_args or f.sz_res() > 1):
            raise ValueError(f"{f.name()}: compiled kernels take (x, u, p) and give one output")
    with tempfile.TemporaryDirectory() as tmp:
        gen = ca.CodeGenerator(f"{prefix}.c", {"with_header": False, "casadi_int": "long long int"})
        for f in functions:
            gen.add(f)
        gen.generate(tmp + os.sep)
        source = Path(tmp, f"{prefix}.c").read_text()
    digest = hashlib.sha256((source + ca.__version__ + " ".join(_CFLAGS)).encode()).hexdigest()[:16]
    lib_path = cache_dir() / f"{prefix}_{digest}.so"
    if not lib_path.exists():
        _build(source, lib_path)
    key = str(lib_path)
    if key not in _LOADED:
        _LOADED[key] = ctypes.CDLL(key)
    lib = _LOADED[key]
    out = {}
    for f in functions:
        address = ctypes.cast(getattr(lib, f.name()), ctypes.c_void_p).value
        out[f.name()] = CompiledFunction(f.name(), address, int(f.sz_iw()), int(f.sz_w()), lib,
                                         int(f.sz_arg()), int(f.sz_res()))
    return out


def _build(source: str, lib_path: Path) -> None:
    compiler = shutil.which(os.environ.get("CC", "gcc")) or shutil.which("cc")
    if compiler is None:
        raise PneusimError("no C compiler found (gcc or $CC); scripts/setup.sh installs gcc")
    with tempfile.TemporaryDirectory(dir=lib_path.parent) as tmp:
        c_file = Path(tmp, "model.c")
        c_file.write_text(source)
        tmp_lib = Path(tmp, lib_path.name)
        cmd = [compiler, *_CFLAGS, "-shared", "-fPIC", "-o", str(tmp_lib), str(c_file), "-lm"]
        result = subprocess.run(cmd, capture_output=True, text=True)
        if result.returncode != 0:
            raise PneusimError(f"compiling the model failed: {result.stderr.strip()[:2000]}")
        os.replace(tmp_lib, lib_path)  # atomic: parallel workers never load a half-written file
