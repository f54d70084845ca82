#!/usr/bin/env bash
# Engine benchmark (issue 2): examples/box-deposit.toml (1 000 spheres into a box, to t = 1.5 s) and a
# 10 000-sphere box deposit (first 0.5 s), on 1 and 2 threads. Prints markdown for
# bench/RESULTS.md. Usage: bench/engine/run.sh [BUILD_DIR]   (default build/release)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build/release}
rubble=$build/apps/rubble
out=$(mktemp -d)
echo "machine: $(nproc --all) cores, $(lscpu | sed -n 's/^Model name: *//p'); date: $(date -u +%F)"
for threads in 1 2; do
  OMP_NUM_THREADS=$threads "$rubble" run "$root/examples/box-deposit.toml" --out "$out/default-$threads" -q > /dev/null
  OMP_NUM_THREADS=$threads "$rubble" run "$root/bench/engine/box-deposit-10000.toml" --out "$out/deposit10k-$threads" -q > /dev/null
  /usr/bin/python3 "$root/bench/engine/summarize.py" \
    "$out/default-$threads/run.h5=default scene, $threads thread(s)" \
    "$out/deposit10k-$threads/run.h5=10 000-sphere box deposit, $threads thread(s)"
done
rm -rf "$out"
