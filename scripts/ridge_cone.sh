#!/usr/bin/env bash
# The 8 m keel against the cone (scenes/ridge_keel_8m_cone.json), hybrid and full-particle.
#   bash scripts/ridge_cone.sh [DURATION_S]    (default: the scene's 29 s; both runs use it)
# Builds, makes the ridge file if missing (`hybridsim ridge` on the run scene itself: the keel
# settles under plates of the run's own sheet, with its ice; ~30 s CPU, 1352 blocks), runs the scene in hybrid
# mode and with conversion = all_at_start (the full-particle reference: 2.7x the peak particle
# count and 2.8x the wall time over the old scene's 6 s, docs/bridge.md), and plots both into out/. The run reports print wall time, peak particle
# count and conversion statistics side by side.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh hybridsim
mkdir -p out
RIDGE=scenes/ridge_keel_8m_31m_ridge.h5  # blocks.ridge_file of the scene (and of paper_keel_7_9m)
# Made when missing, and again when the run refuses it as made from another definition or ice.
if [ ! -f "$RIDGE" ] || ./build/hybridsim check scenes/ridge_keel_8m_cone.json 2>&1 | grep -q "/blocks/ridge_file"; then
  ./build/hybridsim ridge scenes/ridge_keel_8m_cone.json
fi
extra=()
[ $# -ge 1 ] && extra=(--set "time.duration=$1")
for mode in hybrid all_at_start; do
  ./build/hybridsim run scenes/ridge_keel_8m_cone.json "${extra[@]}" --set "blocks.conversion=$mode" \
    -o "out/ridge_keel_8m_cone_${mode}.h5" | tee "out/ridge_keel_8m_cone_${mode}.txt"
  /usr/bin/python3 tools/plot_run.py "out/ridge_keel_8m_cone_${mode}.h5" -o out
done
