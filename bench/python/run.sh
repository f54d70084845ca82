#!/usr/bin/env bash
# Python module overhead (issue 21): a Python loop of sim.step() against `rubble run` on the
# default accretion, one thread. Usage: bench/python/run.sh [BUILD_DIR] [STEPS] [REPEATS]
# (default build/ci, 1000 steps, 3 rounds). Prints markdown for bench/RESULTS.md ("Python module").
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build/ci}
echo "machine: $(nproc --all) cores, $(lscpu | sed -n 's/^Model name: *//p'); date: $(date -u); load before: $(cut -d' ' -f1-3 /proc/loadavg)"
OMP_NUM_THREADS=1 PYTHONPATH="$build/python" /usr/bin/python3 "$root/bench/python/step_loop.py" \
  "$build/apps/rubble" "${2:-1000}" "${3:-3}"
