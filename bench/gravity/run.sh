#!/usr/bin/env bash
# Reproduces the "## Gravity" figures of bench/RESULTS.md and docs/gravity-error-vs-time.png.
#   bench/gravity/run.sh            (from the repository root; BUILD=dir to reuse a build tree,
#                                    BENCH_BIN=path to use an existing bench_gravity binary)
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
BUILD="${BUILD:-$ROOT/build-bench}"
if [ -z "${BENCH_BIN:-}" ]; then
  cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$BUILD" --target bench_gravity -j2 >/dev/null
  BENCH_BIN="$BUILD/bench/gravity/bench_gravity"
fi
OUT="$ROOT/bench/gravity"
echo "# machine: $(lscpu | grep 'Model name' | sed 's/ \+/ /g'), $(nproc --all) cores; $(date); load: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "## direct sum (best of 3)"
"$BENCH_BIN" --direct-rate --n 10000,30000 --threads 1,2 --reps 3
echo
echo "## tree, uniform sphere (best of 3, tree build included)"
"$BENCH_BIN" --dist uniform --n 1000,10000,100000,1000000 --theta 0.3,0.5,0.7,1.0 --order 1,2 \
  --threads 1,2 --reps 3 --csv "$OUT/results_uniform.csv"
echo
echo "## tree, Plummer sphere (best of 3)"
"$BENCH_BIN" --dist plummer --n 100000 --theta 0.3,0.5,0.7,1.0 --order 1,2 --threads 1 --reps 3 \
  --csv "$OUT/results_plummer.csv"
echo "# load at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
/usr/bin/python3 "$OUT/plot.py" "$OUT/results_uniform.csv" "$ROOT/docs/gravity-error-vs-time.png"
