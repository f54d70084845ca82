#!/usr/bin/env bash
# Reproduces the "## Solver (FCLib)" table of bench/RESULTS.md: the four shared FCLib problems
# (../shared/fclib) at tolerances 1e-4 and 1e-8, best of 3, for the plain NLGS sweep, the
# over-relaxed sweep (omega = 1.6) and NLGS + Levenberg-Marquardt polish (rubble fclib's default).
#   bench/solver/run.sh            (from anywhere; BUILD=dir to reuse a build tree,
#                                   BENCH_BIN=path to use an existing bench_fclib binary)
# The charts of docs/accuracy-vs-speed.md come from bench/solver/charts.py.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
BUILD="${BUILD:-$ROOT/build-bench}"
FCLIB="${FCLIB:-$ROOT/../shared/fclib}"
if [ -z "${BENCH_BIN:-}" ]; then
  cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$BUILD" --target bench_fclib -j2 >/dev/null
  BENCH_BIN="$BUILD/bench/solver/bench_fclib"
fi
FILES=("$FCLIB/Capsules-i125-1213.hdf5" "$FCLIB/fclib_local_problem_test_BoxesStack.hdf5"
       "$FCLIB/Box_Stacks-i0122-82-5_local.hdf5" "$FCLIB/Spheres-i099-356-679_local.hdf5")
echo "# machine: $(lscpu | grep 'Model name' | sed 's/ \+/ /g'), $(nproc --all) cores; $(date); load: $(cut -d' ' -f1-3 /proc/loadavg)"
for method in "none" "none --omega 1.6" "newton"; do
  # shellcheck disable=SC2086
  "$BENCH_BIN" "${FILES[@]}" --tolerances 1e-4,1e-8 --max-iterations 100000 --reps 3 --polish $method
done | tee "$ROOT/bench/solver/fclib_table.jsonl"
echo "# load at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
