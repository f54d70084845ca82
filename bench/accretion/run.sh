#!/usr/bin/env bash
# Accretion benchmark (issue 5): the accretion study's clouds (seed 001) run to rest with
# dt = "auto" and until = "rest": wall and CPU time to rest, steps/s and the time split per stage.
# Usage: bench/accretion/run.sh [BUILD_DIR] [CASE...]   (default build/release; cases below)
# Cases: spheres-1000 spheres-3375 spheres-8000 polyhedra-1000 (and any examples/accretion/*.toml
# name, e.g. spheres-27000). Prints markdown for bench/RESULTS.md ("## Accretion"); the run folders
# are kept in $OUT (default a temporary folder) for `rubble post`, with the progress lines in
# $OUT/NAME.log.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build/release}
shift || true
cases=("$@")
[ ${#cases[@]} -gt 0 ] || cases=(spheres-1000 spheres-3375 spheres-8000 polyhedra-1000)
rubble=$build/apps/rubble
out=${OUT:-$(mktemp -d)}
echo "machine: $(nproc) cores, $(lscpu | sed -n 's/^Model name: *//p'); date: $(date -u +%F); OMP_NUM_THREADS=${OMP_NUM_THREADS:-2}"
for name in "${cases[@]}"; do
  scene=$root/examples/accretion/$name.toml
  /usr/bin/time -f "%e %U %S" -o "$out/$name.time" \
    env OMP_NUM_THREADS=${OMP_NUM_THREADS:-2} "$rubble" run "$scene" --out "$out/$name" --checkpoint-minutes 0 \
    > "$out/$name.log" 2>&1 || echo "(exit $? for $name, see $out/$name.log)"
  read -r wall user system < "$out/$name.time"
  /usr/bin/python3 "$root/bench/accretion/summarize.py" "$out/$name/run.h5" "$name" "$wall" "$user" "$system"
done
echo "runs kept in $out"
