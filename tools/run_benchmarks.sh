#!/usr/bin/env bash
# Runs the built-in benchmarks and keeps their figures per machine.
#   tools/run_benchmarks.sh [NAME ...]        (default: granular bonded; `hybrid` needs the paper-size
#                                             ridge cached once, see `hybridsim bench hybrid`'s message)
#   RANKS=2 tools/run_benchmarks.sh           the same under mpirun -np 2 (strong scaling;
#                                             the CSV name column becomes e.g. granular@2)
# Prints each benchmark's JSON line and appends a CSV row to bench/results-<host>.csv
# (date, commit, name, particles, steps, wall_s, particle_steps_per_s, peak_rss_mb, cpu).
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
# The code measured: the commit, marked -dirty when tracked files differ from it.
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
[ "$commit" != unknown ] && ! git diff --quiet HEAD -- 2>/dev/null && commit="$commit-dirty"
for n in "${names[@]}"; do
  if [ "${RANKS:-1}" -gt 1 ]; then
    line=$(OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun --bind-to none -np "$RANKS" "$exe" bench "$n")
  else
    line=$("$exe" bench "$n")
  fi
  echo "$line"
  /usr/bin/python3 - "$line" "$commit" >> "$csv" <<'PY'
import json, sys, datetime
j = json.loads(sys.argv[1])
name = j["name"] + (f"@{j['ranks']}" if j.get("ranks", 1) > 1 else "")
print(",".join(str(x) for x in [datetime.date.today(), sys.argv[2], name, j["particles"], j["steps"],
      round(j["wall_s"], 3), round(j["particle_steps_per_s"]), round(j["peak_rss_mb"], 1), '"' + j["cpu"] + '"']))
PY
done
echo "appended to $csv"
