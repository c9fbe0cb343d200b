"""Benchmarks run on pneusim's arithmetic path: ``import pneusim`` before any benchmark module loads NumPy, so
that OpenBLAS starts with the kernels :mod:`pneusim.arithmetic` pins (a module importing NumPy first would
keep this CPU's own)."""

import pneusim  # noqa: F401 - first, for the pin
