#!/usr/bin/env bash
# Instructions per engine step of the node benchmark's grid scene, counted by valgrind
# (deterministic, unlike wall time on a shared machine): the difference between runs of
# 50 + K steps and of 50 steps (imports, scene load and first-step set-up cancel), divided by K.
# Usage: bench/instructions.sh [bodies=100] [K=200]   (needs valgrind; ~1 minute)
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-100}
K=${2:-200}
PY=${PY:-.venv/bin/python}
prog='
import sys, tempfile, warnings
sys.path.insert(0, "bench")
import bench_node, contact_sim as cs
world = cs.load_scene(bench_node.grid_scene(int(sys.argv[1]), tempfile.mktemp(suffix=".yaml")))
warnings.simplefilter("ignore")
for _ in range(50 + int(sys.argv[2])):
    world.step()
'
count() {
  valgrind --trace-children=yes --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null \
    "$PY" -c "$prog" "$N" "$1" 2>&1 | grep "I *refs" | tail -1 | awk '{gsub(",", "", $4); print $4}'
}
base=$(count 0)
total=$(count "$K")
python3 -c "print(f'{($total - $base) / $K / 1e6:.2f} million instructions per step, $N bodies')"
