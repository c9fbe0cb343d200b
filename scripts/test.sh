#!/usr/bin/env bash
# Set everything up (idempotent) and run the test suite.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
# two workers (the machines have two cores); a test file stays on one worker so its fixtures run once
exec .venv/bin/python -m pytest -n 2 --dist loadfile tests "$@"
