#!/usr/bin/env bash
# Set up pneusim on a fresh Debian/Ubuntu machine: system packages, .venv, the
# package and its dependencies. Idempotent: a second run only checks and exits.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"

need_apt=()
for pkg in libsundials-dev python3-venv python3-dev gcc g++ pkg-config; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || need_apt+=("$pkg")
done
if [ ${#need_apt[@]} -gt 0 ]; then
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  echo "setup: installing system packages: ${need_apt[*]}"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

python="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  "$python" -m venv .venv
fi
stamp=.venv/.pneusim-installed
# reinstall when the packaging or a compiled extension (its .pyx or a C header it includes) changed
want="$(cat pyproject.toml setup.py pneusim/*/*.pyx pneusim/*/*.h | sha256sum | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing pneusim and its dependencies into .venv"
  .venv/bin/python -m pip install -q --upgrade pip wheel setuptools
  # scikits.odes 2.7.x builds its Cython extension against Debian's SUNDIALS 6.
  SUNDIALS_INST=/usr .venv/bin/python -m pip install -q "scikits.odes>=2.7,<2.8"
  # our own extension cimports scikits.odes' declarations, so it builds without isolation
  .venv/bin/python -m pip install -q "cython>=3" "setuptools>=77" numpy
  # --no-compile: pip compiles one file after the other (a minute); compileall does it side by side.  Compiled once
  # here because where PYTHONDONTWRITEBYTECODE is set (containers and CI images set it) Python never writes them, and
  # every process compiled each module it imported again, about 0.45 s a start (docs/decisions/0128). Only a
  # speed-up: a file that does not compile (a dependency's file for another Python) is read as source.
  .venv/bin/python -m pip install -q --no-compile --no-build-isolation -e ".[test]"
  .venv/bin/python -m compileall -q -j 0 .venv/lib pneusim sysid >/dev/null \
    || echo "setup: some installed files could not be byte-compiled; Python reads them as source (slower starts)"
  echo "$want" > "$stamp"
fi
.venv/bin/python -c "import pneusim, sysid, scikits.odes.ode" || { echo "setup: import check failed" >&2; exit 1; }
echo "setup: ready (.venv)"
