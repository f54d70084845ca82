#!/usr/bin/env bash
# Accretion benchmark (issue 5): the accretion study's clouds (the LMGC90 accretion paper) run to rest with
# dt = "auto" and until = "rest": wall and CPU time to rest, steps/s, the time split per stage and
# the NLGS sweeps per step over the run.
# Usage: bench/accretion/run.sh [BUILD_DIR] [CASE...]   (default build/release; cases below)
# Cases: spheres-1000 spheres-3375 spheres-8000 polyhedra-1000 (and any examples/accretion/*.toml
# name, e.g. spheres-27000). One run at a time, OMP_NUM_THREADS=1 unless set (CPU seconds are the
# measure on the shared machine; the load average before and after each run is printed).
# LIMIT_S (default 1200) caps each run's wall time: the run gets SIGINT (it writes a checkpoint and
# its run file stays readable) and the summary extrapolates to rest from the rate, saying so.
# Prints markdown for bench/RESULTS.md ("## Accretion"); the run folders are kept in $OUT (default
# a temporary folder) for `rubble post`, with the progress lines in $OUT/NAME.log.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build/release}
shift || true
cases=("$@")
[ ${#cases[@]} -gt 0 ] || cases=(spheres-1000 spheres-3375 spheres-8000 polyhedra-1000)
rubble=$build/apps/rubble
out=${OUT:-$(mktemp -d)}
threads=${OMP_NUM_THREADS:-1}
echo "machine: $(nproc --all) cores, $(lscpu | sed -n 's/^Model name: *//p'); date: $(date -u); OMP_NUM_THREADS=$threads"
for name in "${cases[@]}"; do
  scene=$root/examples/accretion/$name.toml
  load_before=$(uptime | sed 's/.*load average: //')
  status=0
  timeout -s INT "${LIMIT_S:-1200}" /usr/bin/time -v -o "$out/$name.timev" \
    env OMP_NUM_THREADS="$threads" "$rubble" run "$scene" --out "$out/$name" --checkpoint-minutes 0 \
    > "$out/$name.log" 2>&1 || status=$?
  load_after=$(uptime | sed 's/.*load average: //')
  [ "$status" = 0 ] || echo "(exit $status for $name: stopped at the time limit or failed, see $out/$name.log)"
  /usr/bin/python3 "$root/bench/accretion/summarize.py" "$out/$name/run.h5" "$name" "$out/$name.timev" \
    "$load_before" "$load_after"
done
echo "runs kept in $out"
