"""The BLAS kernels pinned at ``import pneusim``: the same arithmetic path on every x86-64 machine with AVX2."""

import os
import subprocess
import sys

import pytest

from pneusim.arithmetic import PINNED_CORETYPE, _cpu_flags, pin_blas_kernels

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
