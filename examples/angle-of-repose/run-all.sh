#!/bin/sh
# Run the four angle-of-repose heaps one after the other on one thread, each timed by
# /usr/bin/time -v (CPU time = user + system), with the load average before and after, then measure.
# Usage: examples/angle-of-repose/run-all.sh [RUBBLE] [OUT_DIR]
#   RUBBLE: the rubble program (default: build/ci/apps/rubble); OUT_DIR: where the runs go (default: heaps-output)
set -eu
here=$(dirname "$0")
rubble=${1:-build/ci/apps/rubble}
out=${2:-heaps-output}
mkdir -p "$out"
for mu_r in 0 0.1 0.05 0.2; do
  name=heap-mur$mu_r
  echo "== $name: start $(date -u '+%Y-%m-%d %H:%M:%S') UTC, load $(cut -d' ' -f1-3 /proc/loadavg)"
  OMP_NUM_THREADS=1 nice -n 5 /usr/bin/time -v "$rubble" run "$here/$name.toml" --out "$out/$name" \
    > "$out/$name.log" 2>&1
  echo "== $name: end $(date -u '+%Y-%m-%d %H:%M:%S') UTC, load $(cut -d' ' -f1-3 /proc/loadavg)"
  grep -E "User time|System time|Elapsed|Maximum resident" "$out/$name.log"
  tail -n 30 "$out/$name.log" | grep -E "^rubble run: (at rest|stopped|reached|end)" || true
done
/usr/bin/python3 "$here/measure.py" "$out"/heap-mur0/run.h5 "$out"/heap-mur0.05/run.h5 \
  "$out"/heap-mur0.1/run.h5 "$out"/heap-mur0.2/run.h5 \
  --plot "$here/angle-of-repose.png"
