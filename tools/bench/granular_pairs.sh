#!/bin/bash
# Paired runs of `hybridsim bench granular` and LAMMPS's gran/hooke/history on the same settled pack,
# one core each (taskset -c CORE), in turn: prints each pair's particle-steps/s and their ratio.
# Quote the median ratio. Needs build/hybridsim, Debian's `lammps` (lmp) and the pack written by
#   build/hybridsim bench granular --lammps-data /tmp/granular_pack.data
# Usage: tools/bench/granular_pairs.sh [PAIRS (6)] [CORE (1)] [PACK (/tmp/granular_pack.data)]
set -euo pipefail
pairs=${1:-6}
core=${2:-1}
pack=${3:-/tmp/granular_pack.data}
cd "$(dirname "$0")/../.."
for i in $(seq 1 "$pairs"); do
  h=$(taskset -c "$core" ./build/hybridsim bench granular 2>/dev/null |
      python3 -c "import json,sys; j=json.loads(sys.stdin.read()); print(j['particle_steps_per_s'], j['peak_rss_mb'])")
  l=$(OMP_NUM_THREADS=1 taskset -c "$core" lmp -in tools/bench/granular.lmp -var data "$pack" -log none 2>&1 |
      awk '/Loop time/ {print $4}')
  python3 -c "
h, mb = map(float, '$h'.split()); lr = 30375 * 2000 / $l
print('pair $i: hybridsim %.3g particle-steps/s (%.1f MB), LAMMPS %.3g (loop %s s), ratio %.3f' % (h, mb, lr, '$l', h / lr))"
done
