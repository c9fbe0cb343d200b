#!/usr/bin/env bash
# Set everything up (idempotent) and run the test suite.
#   bash scripts/test.sh            everything (what CI runs)
#   bash scripts/test.sh --quick    the quick tier for day-to-day work: no `slow` (over about 2 s) or `minutes` tests
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
if [ "${1:-}" = "--quick" ]; then
  shift
  set -- -m "not slow and not minutes" "$@"
fi
# two workers (the machines have two cores); "worksteal" lets an idle worker take queued tests from a
# busy one, so the few minute-long fit tests do not queue behind each other on one worker
exec .venv/bin/python -m pytest -n 2 --dist worksteal tests "$@"
