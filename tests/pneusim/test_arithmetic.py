"""The BLAS kernels and NumPy's SIMD loops pinned at ``import pneusim``: the same arithmetic path on every x86-64
machine with AVX2."""

import os
import subprocess
import sys

import pytest

from pneusim.arithmetic import PINNED_CORETYPE, _cpu_flags, pin_blas_kernels, pin_numpy_dispatch

AVX2_FMA = {"sse2", "avx", "avx2", "fma"}


def test_pins_where_unset_on_an_avx2_cpu():
    env = {}
    assert pin_blas_kernels(env, "x86_64", AVX2_FMA, numpy_loaded=False) == PINNED_CORETYPE
    assert env == {"OPENBLAS_CORETYPE": PINNED_CORETYPE}


@pytest.mark.parametrize("env, machine, flags, numpy_loaded", [
    ({"OPENBLAS_CORETYPE": "Sandybridge"}, "x86_64", AVX2_FMA, False),   # the user's choice is kept
    ({}, "x86_64", AVX2_FMA, True),                                       # too late: NumPy chose already
    ({}, "aarch64", {"asimd", "fp"}, False),                              # no x86 kernels to pin
    ({}, "x86_64", {"sse2", "avx"}, False),                               # Haswell's kernels would not run
    ({}, "x86_64", {"avx2"}, False),                                      # (they need fused multiply-add too)
])
def test_leaves_the_kernels_alone(env, machine, flags, numpy_loaded):
    before = dict(env)
    assert pin_blas_kernels(env, machine, flags, numpy_loaded=numpy_loaded) is None
    assert env == before


def test_reads_the_cpu_flags(tmp_path):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nmodel name\t: a CPU\nflags\t\t: fpu sse2 avx2 fma\n\nprocessor\t: 1\n")
    assert _cpu_flags(str(cpuinfo)) == {"fpu", "sse2", "avx2", "fma"}
    assert _cpu_flags(str(tmp_path / "missing")) == set()


def _kernels_in_a_fresh_process(code: str, **env_changes) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    env.update(env_changes)
    out = subprocess.run([sys.executable, "-c", code + "\nfrom pneusim.arithmetic import blas_kernels\n"
                          "print(','.join(blas_kernels()))"],
                         env=env, capture_output=True, text=True, check=True)
    return out.stdout.strip().split(",")


@pytest.mark.skipif(not {"avx2", "fma"} <= _cpu_flags(), reason="the CPU has no AVX2 with FMA")
def test_every_blas_library_runs_the_pinned_kernels():
    """NumPy's and SciPy's OpenBLAS both load with the pinned kernels after ``import pneusim``, whatever this
    CPU's own would be; a core type set by the user wins; a process that loaded NumPy first keeps its own."""
    assert set(_kernels_in_a_fresh_process("import pneusim")) == {PINNED_CORETYPE}
    assert set(_kernels_in_a_fresh_process("import pneusim", OPENBLAS_CORETYPE="Sandybridge")) == {"Sandybridge"}
    own = _kernels_in_a_fresh_process("import numpy, os, pneusim\nassert 'OPENBLAS_CORETYPE' not in os.environ")
    assert own == _kernels_in_a_fresh_process("import numpy")


@pytest.mark.parametrize("numpy_version, names", [
    ("2.4.6", "X86_V4 AVX512_ICL AVX512_SPR"),        # NumPy's x86-64 level names
    ("3.0.0rc1", "X86_V4 AVX512_ICL AVX512_SPR"),
    ("2.3.5", "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR"),
    ("1.26.4", "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR"),
])
def test_numpy_loops_above_avx2_are_switched_off_by_the_installed_numpys_names(numpy_version, names):
    env = {}
    assert pin_numpy_dispatch(env, "x86_64", AVX2_FMA, numpy_loaded=False, numpy_version=numpy_version) == names
    assert env == {"NPY_DISABLE_CPU_FEATURES": names}


@pytest.mark.parametrize("env, machine, flags, numpy_loaded", [
    ({"NPY_DISABLE_CPU_FEATURES": "X86_V3"}, "x86_64", AVX2_FMA, False),  # the user's choice is kept
    ({}, "x86_64", AVX2_FMA, True),                                         # too late: NumPy dispatched already
    ({}, "aarch64", {"asimd", "fp"}, False),
    ({}, "x86_64", {"sse2", "avx"}, False),                                 # an AVX2 machine's loops would not run
])
def test_leaves_the_numpy_loops_alone(env, machine, flags, numpy_loaded):
    before = dict(env)
    assert pin_numpy_dispatch(env, machine, flags, numpy_loaded=numpy_loaded, numpy_version="2.4.6") is None
    assert env == before


def _numpy_loops_in_a_fresh_process(code: str, **env_changes) -> tuple[list[str], str]:
    """The dispatch targets and a digest of ``exp``, ``log`` and ``power`` on fixed arguments in a new process."""
    env = {k: v for k, v in os.environ.items() if k != "NPY_DISABLE_CPU_FEATURES"}
    env.update(env_changes)
    out = subprocess.run([sys.executable, "-c", code + """
import hashlib, numpy as np
from pneusim.arithmetic import numpy_dispatch
x = np.linspace(-5.0, 5.0, 100001)
p = np.linspace(1e4, 8e5, 100001)
digest = hashlib.sha256(np.exp(x).tobytes() + np.log(p).tobytes() + np.power(p, 0.2857).tobytes()).hexdigest()
print(",".join(numpy_dispatch()), digest)"""], env=env, capture_output=True, text=True, check=True)
    targets, digest = out.stdout.split()
    return targets.split(","), digest


@pytest.mark.skipif(not {"avx2", "fma"} <= _cpu_flags(), reason="the CPU has no AVX2 with FMA")
def test_numpy_runs_an_avx2_machines_loops_after_import_pneusim():
    """After ``import pneusim`` NumPy dispatches to no AVX-512 loop and its transcendental functions give the
    bits of a process whose AVX-512 loops the user switched off by hand; a process that loaded NumPy first keeps
    its CPU's own loops (a user's variable winning is :func:`test_leaves_the_numpy_loops_alone`'s first case)."""
    targets, digest = _numpy_loops_in_a_fresh_process("import pneusim")
    assert not any(t.startswith(("X86_V4", "AVX512")) for t in targets)
    names = pin_numpy_dispatch({}, "x86_64", AVX2_FMA, numpy_loaded=False)
    by_hand = _numpy_loops_in_a_fresh_process("import numpy", NPY_DISABLE_CPU_FEATURES=names)
    assert digest == by_hand[1]
    own = _numpy_loops_in_a_fresh_process("import numpy, pneusim")
    assert own == _numpy_loops_in_a_fresh_process("import numpy")
