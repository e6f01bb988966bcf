#!/usr/bin/env bash
# Installs the Debian packages (idempotent), configures and builds hybridsim (Release).
#   bash scripts/build.sh [TARGET ...]    (default: everything, tests included)
# Result: build/hybridsim and the test executables under build/tests.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
if [ $# -gt 0 ]; then
  cmake --build build -j"$(nproc)" --target "$@"
else
  cmake --build build -j"$(nproc)"
fi
