#!/usr/bin/env bash
# Runs the built-in benchmarks and keeps their figures per machine.
#   tools/run_benchmarks.sh [NAME ...]        (default: granular bonded)
# Prints each benchmark's JSON line and appends a CSV row to bench/results-<host>.csv.
# Run on a quiet machine: the figures are single-core wall-clock rates.
set -euo pipefail
cd "$(dirname "$0")/.."
exe=build/hybridsim
[ -x "$exe" ] || { echo "error: $exe not found; build first (bash scripts/build.sh)" >&2; exit 2; }
names=("$@")
[ ${#names[@]} -eq 0 ] && names=(granular bonded)
mkdir -p bench
csv="bench/results-$(hostname).csv"
[ -f "$csv" ] || echo "date,commit,name,particles,steps,wall_s,particle_steps_per_s,peak_rss_mb,cpu" > "$csv"
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
for n in "${names[@]}"; do
  line=$("$exe" bench "$n")
  echo "$line"
  /usr/bin/python3 - "$line" "$commit" >> "$csv" <<'PY'
import json, sys, datetime
j = json.loads(sys.argv[1])
print(",".join(str(x) for x in [datetime.date.today(), sys.argv[2], j["name"], j["particles"], j["steps"],
      round(j["wall_s"], 3), round(j["particle_steps_per_s"]), round(j["peak_rss_mb"], 1), '"' + j["cpu"] + '"']))
PY
done
echo "appended to $csv"
