#!/usr/bin/env bash
# Issue 9 scaling benchmark: single-thread CPU time per step vs N for settled box deposits of spheres
# (N = 1e3 ... 1e5) and polyhedra (N = 1e3 ... 3e4), the fitted exponent, docs/scaling.png, and the
# peak resident memory per grain at the largest N. The method is in bench/engine/scaling.py's
# docstring; results go to bench/RESULTS.md, "Performance targets (issue 9)". About 15-20 min of CPU.
# A case that fails (a settled scene refused, a crash) is reported with its log and skipped; the
# others are still measured, and the script then exits with 1.
# Usage: bench/engine/scaling.sh [BUILD_DIR] [scaling.py options: --quick, --only polyhedron-30000, --plot-only]
#   (default BUILD_DIR build/release; work files and the CSV in /tmp/rubble-scaling-bench)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build/release}
shift || true
echo "machine: $(nproc --all) cores, $(lscpu | sed -n 's/^Model name: *//p'); date: $(date -u '+%F %H:%M UTC'); load: $(cut -d' ' -f1-3 /proc/loadavg)"
exec /usr/bin/python3 "$root/bench/engine/scaling.py" "$build" "$@"
