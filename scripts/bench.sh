#!/usr/bin/env bash
# Set everything up and run the benchmarks (pytest-benchmark), printing ratios against the peers.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
exec .venv/bin/python -m pytest benchmarks --benchmark-only --benchmark-columns=min,mean,rounds -s "$@"
