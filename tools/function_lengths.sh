#!/usr/bin/env bash
# Lists the longest functions under a source tree (lines from the signature to the closing brace,
# lambdas inside counted with their function), and fails when one is over a limit.
#   bash tools/function_lengths.sh [DIR=src] [LIMIT=150] [TOP=15]
# Needs universal-ctags (scripts/install-deps.sh installs it).
set -euo pipefail
dir=${1:-src}; limit=${2:-150}; top=${3:-15}
ctags -R --languages=C++ --kinds-C++=f --fields=+ne -x --_xformat='%{end} %{line} %F %N' "$dir" 2>/dev/null |
  awk '$1 ~ /^[0-9]+$/ {print $1 - $2 + 1, $3 ":" $2, $4}' | sort -n | tail -n "$top" |
  awk -v lim="$limit" '{print} $1 > lim {bad = 1} END {if (bad) {print "over " lim " lines: the lines above with a larger count"; exit 1}}'
