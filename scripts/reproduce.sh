#!/usr/bin/env bash
# Set everything up (idempotent) and run the main job: both paper scenarios and their reports.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
bash scripts/setup.sh
out="${1:-results}"
# --overwrite: these folders are this script's own; a scenario file edited since the last run replaces them
.venv/bin/pneusim run scenarios/paper1-online-rls.toml --out "$out/paper1-online-rls" --overwrite
.venv/bin/pneusim run scenarios/paper2-multisine.toml --out "$out/paper2-multisine" --overwrite
echo "reports: $out/paper1-online-rls/report.html and $out/paper2-multisine/report.html"
