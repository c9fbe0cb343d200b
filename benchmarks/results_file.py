"""Where a benchmark writes its table: ``docs/results/<name>.md``, headed by what was measured where.

Every table a benchmark prints is also written, so the numbers a document quotes come from a file
a script regenerates, never from a sentence typed by hand.  The header line names

* the **commit** (``git rev-parse --short HEAD``, with ``+ uncommitted changes`` when the package
  sources differ from it),
* the **machine** (CPU model, logical cores, the BLAS kernels and NumPy's SIMD loops the process runs (pinned
  by ``import pneusim``, :mod:`pneusim.arithmetic`, or chosen by ``OPENBLAS_CORETYPE`` and
  ``NPY_DISABLE_CPU_FEATURES``), the 1-minute load average when the table is written),
* the **date** (UTC) and
* the **command** that produced it (the pytest arguments, and every ``PNEUSIM_*``, ``OPENBLAS_*`` or
  ``NPY_DISABLE_CPU_FEATURES`` variable set in the environment, but those ``import pneusim`` set itself).

``PNEUSIM_RESULTS_DIR`` writes somewhere else (a scratch folder for a quick look); by default the
file goes to ``docs/results/`` of this repository, where ``git diff`` shows what moved.
"""

from __future__ import annotations

import datetime
import os
import platform
import shlex
import subprocess
import sys
from pathlib import Path

from pneusim.arithmetic import blas_kernels, numpy_dispatch, numpy_pinned_here, pinned_here

ROOT = Path(__file__).resolve().parents[1]
RESULTS_DIR = ROOT / "docs" / "results"
#: the sources whose state the commit line vouches for
SOURCES = ("pneusim", "sysid", "benchmarks", "setup.py", "pyproject.toml")

__all__ = ["commit", "machine", "command", "header", "write_results"]


def _git(*args: str) -> str:
    try:
        done = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return ""
    return done.stdout.strip() if done.returncode == 0 else ""


def commit() -> str:
    """The short commit hash of ``HEAD``, and whether the package sources differ from it."""
    head = _git("rev-parse", "--short", "HEAD") or "unknown commit"
    dirty = _git("status", "--porcelain", "--", *SOURCES)
    return f"{head} + uncommitted changes" if dirty else head


def machine() -> str:
    """CPU model, logical cores, the BLAS kernels and NumPy loops this process runs, and the 1-minute load
    average."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            model = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), model)
    except OSError:
        pass
    parts = [model, f"{os.cpu_count()} cores"]
    kernels = sorted(set(blas_kernels()))
    if kernels:
        parts.append(f"BLAS kernels {', '.join(kernels)}" + (" (pinned by pneusim)" if pinned_here() else ""))
    loops = numpy_dispatch()
    parts.append(f"NumPy loops {', '.join(loops) or 'baseline'}"
                 + (" (pinned by pneusim)" if numpy_pinned_here() else ""))
    try:
        parts.append(f"load {os.getloadavg()[0]:.1f}")
    except OSError:
        pass
    return ", ".join(parts)


def command() -> str:
    """The pytest command line that is running, with the ``PNEUSIM_*``, ``OPENBLAS_*`` and
    ``NPY_DISABLE_CPU_FEATURES`` variables set (not those pneusim set itself)."""
    env = " ".join(f"{k}={shlex.quote(v)}" for k, v in sorted(os.environ.items())
                   if k.startswith(("PNEUSIM_", "OPENBLAS_", "NPY_DISABLE_CPU_FEATURES"))
                   and k != "PNEUSIM_RESULTS_DIR"
                   and not (k == "OPENBLAS_CORETYPE" and pinned_here())
                   and not (k == "NPY_DISABLE_CPU_FEATURES" and numpy_pinned_here()))
    return " ".join(p for p in (env, "pytest", shlex.join(sys.argv[1:])) if p)


def header() -> str:
    """One Markdown line: commit, machine, date and command of the measurement."""
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return f"Measured at commit `{commit()}` on {machine()}, {date}, by `{command()}`."


def write_results(name: str, title: str, body: str) -> Path:
    """Write ``<results dir>/<name>.md``: the title, the header line, then ``body`` (Markdown).

    Parameters
    ----------
    name
        File name without ``.md`` (``fit-robustness``, ``simulator``, ...).
    title
        The table's heading, without the leading ``#``.
    body
        The table and any notes, Markdown.

    Returns
    -------
    Path
        The file written.
    """
    folder = Path(os.environ.get("PNEUSIM_RESULTS_DIR") or RESULTS_DIR)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.md"
    path.write_text(f"# {title}\n\n{header()}\n\n{body.rstrip()}\n", encoding="utf-8")
    print(f"\n(table written to {path})")
    return path
