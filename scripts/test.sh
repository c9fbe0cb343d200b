#!/usr/bin/env bash
# Set everything up (idempotent) and run the test suite.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
# two workers (the machines have two cores); tests are dealt out one by one, so the long fit tests
# of one file do not queue on a single worker
exec .venv/bin/python -m pytest -n 2 --dist load tests "$@"
