#!/usr/bin/env bash
# Set everything up (idempotent) and run the test suite.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
# two workers (the machines have two cores); "worksteal" lets an idle worker take queued tests from a
# busy one, so the few minute-long fit tests do not queue behind each other on one worker
exec .venv/bin/python -m pytest -n 2 --dist worksteal tests "$@"
