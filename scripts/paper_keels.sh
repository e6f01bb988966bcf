#!/usr/bin/env bash
# The paper's keel-depth family (scenes/paper_keel_{0m,4m,6m,7_9m}.json): makes the ridge files
# that are missing, each with its scene's ice (`hybridsim ridge <scene>` writes blocks.ridge_file),
# then checks each scene. Keel 0 m is the consolidated layer alone: no ridge to make.
#   bash scripts/paper_keels.sh [DEPTH ...]    (default: 4m 6m 7_9m)
# Measured 2026-12-02 (shared machine, nice): 4 m 117 s wall (289 blocks), 6 m 496 s wall (736 blocks), 7.9 m
# 32 s wall (1352 blocks; whole keels 3.9 x depth wide, docs/ridge.md "Keel scenes").
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh hybridsim
depths=("$@")
[ ${#depths[@]} -eq 0 ] && depths=(4m 6m 7_9m)
for d in "${depths[@]}"; do
  scene="scenes/paper_keel_${d}.json"
  file="scenes/$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["blocks"]["ridge_file"])' "$scene")"
  [ -f "$file" ] || ./build/hybridsim ridge "$scene"
  ./build/hybridsim check "$scene"
done
./build/hybridsim check scenes/paper_keel_0m.json
