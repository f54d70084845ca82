#!/usr/bin/env bash
# Reproduces the "Gravity every k steps" table of bench/RESULTS.md and docs/gravity-every-k.png:
# the 1000-sphere accretion (examples/accretion-1000.toml, Barnes-Hut theta 0.5, order 2) run for
# STEPS steps with [gravity] evaluate_every = k, k = 1, 2, 4, 8, 16; per step the max and median
# relative error of the acceleration used against the k = 1 field at the same positions, and the
# gravity stage's time (one thread).
#   bench/gravity/every_k.sh        (from anywhere; BUILD=dir to reuse a build tree, STEPS=n)
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
BUILD="${BUILD:-$ROOT/build-bench}"
STEPS="${STEPS:-400}"
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD" --target every_k -j2 >/dev/null
OUT="$ROOT/bench/gravity"
echo "# machine: $(lscpu | grep 'Model name' | sed 's/ \+/ /g'), $(nproc --all) cores; $(date -u); load: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# scene: examples/accretion-1000.toml, $STEPS steps (dt auto = 1.4 s), OMP_NUM_THREADS=1"
OMP_NUM_THREADS=1 /usr/bin/time -f "# CPU: %U s user + %S s sys, peak RSS %M kB" \
  "$BUILD/bench/gravity/every_k" "$ROOT/examples/accretion-1000.toml" --steps "$STEPS" --k 1,2,4,8,16 \
  --csv "$OUT/every_k.csv"
echo "# load at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
/usr/bin/python3 "$OUT/every_k.py" "$OUT/every_k.csv" "$ROOT/docs/gravity-every-k.png"
