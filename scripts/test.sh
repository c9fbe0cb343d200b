#!/usr/bin/env bash
# Set everything up (idempotent) and run the test suite.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
exec .venv/bin/python -m pytest tests "$@"
