#!/bin/sh
# run_then_sane.sh OUT.h5 COMMAND...: run COMMAND -o OUT.h5, then check OUT.h5 on its own
# (compare_runs.py sane: finite, contiguous rows, particles and bonds + broken conserved), so a
# level-ice run entry asserts its own output as well as its exit code (~0.3 s on a 3 s run).
out=$1
shift
"$@" -o "$out" || exit $?
exec /usr/bin/python3 "$(dirname "$0")/compare_runs.py" sane "$out"
