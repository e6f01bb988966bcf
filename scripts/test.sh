#!/usr/bin/env bash
# Sets everything up, builds, and runs the default test suite (labels unit + validation).
#   bash scripts/test.sh [extra ctest args]
# Longer suites are behind labels: ctest --test-dir build -L <label>.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j2 -LE 'slow|benchmark' "$@"
