#!/usr/bin/env bash
# Sets everything up, builds, runs the default scene and plots it.
#   bash scripts/demo.sh [SCENE.json]      (default: the README's default scene)
# Output: out/<scene name>.h5 (+ .xmf for ParaView) and PNG plots in out/.
set -euo pipefail
cd "$(dirname "$0")/.."
SCENE="${1:-scenes/level_ice_cone.json}"
bash scripts/build.sh hybridsim
mkdir -p out
name="$(basename "${SCENE%.json}")"
./build/hybridsim run "$SCENE" -o "out/${name}.h5"
/usr/bin/python3 tools/plot_run.py "out/${name}.h5" -o out
