#!/usr/bin/env bash
# The accretion study end to end (docs/accretion-study.md): runs what is missing of the study's
# runs, one at a time, each to a fixed end past the paper's window (t > 125 min), then draws every
# figure and the study table with `rubble post --study` over all of them.
#
# Usage: examples/accretion/study.sh [RUBBLE] [OUT_DIR] [RUN...]
#   RUBBLE   default build/ci/apps/rubble
#   OUT_DIR  default accretion-study-output: the runs go to OUT_DIR/runs/RUN/, the study to
#            OUT_DIR/study/ (study.csv, study.txt, study_means.csv, study_fits.csv, the PNGs)
#   RUN...   which runs to make, in this order (default: all of SET below); names are
#            SCENE-seedK, SCENE a file of examples/accretion/ without .toml: spheres-1000-seed2
#   Environment:
#   SET         "paper" (default): every run of the study, about 8 h of CPU on one thread, 3.7 h
#               of it the μ = 0.4 and 0.8 runs at 3 375 spheres (bench/RESULTS.md, "The
#               accretion study's long runs", second and third batches); "small": 125 spheres and
#               125 polyhedra, seed 1 (a few CPU seconds with END_TIME=2400 WINDOW=1800)
#   END_TIME    s, where every run stops (default 8100: 135 min, ten snapshots in the window)
#   WINDOW      s, the start of the averaging window (default 7500, the paper's t > 125 min)
#   FIGURES_DIR when set, the study's PNGs are copied there as accretion-study-*.png (docs/)
#   POST        0: make the runs only, no study (default 1)
#   THREADS     OpenMP threads of each run (default 1; the result is the same bits for any count)
#
# Each run is `rubble run SCENE --until end_time --end-time END_TIME` with one snapshot a minute,
# the seed set, and THREADS threads (the result does not depend on it). A run whose run.h5 ended
# (at rest or at its end time) is kept; one that was stopped (a signal, a kill) goes on from its
# newest checkpoint (`rubble run --resume`, docs/checkpoints.md). Frictional runs are
# not run `until = "rest"`: they come to rest long before the window and would stop short of it.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
rubble=${1:-build/ci/apps/rubble}
out=${2:-accretion-study-output}
shift $(($# < 2 ? $# : 2))
end_time=${END_TIME:-8100}
window=${WINDOW:-7500}
set_name=${SET:-paper}
threads=${THREADS:-1}
if ! [[ "$threads" =~ ^[1-9][0-9]*$ ]]; then
  echo "study.sh: THREADS: expected a positive integer, got '$threads'" >&2
  exit 2
fi

if [ $# -gt 0 ]; then
  runs=("$@")
elif [ "$set_name" = small ]; then
  runs=(spheres-125-seed1 polyhedra-125-seed1)
elif [ "$set_name" = paper ]; then
  # Priority order: the mu sweep at 3 375 spheres, the n_s sweeps, then more seeds.
  runs=(spheres-3375-mu0.8-seed1 spheres-3375-mu0.2-seed1 spheres-3375-mu0.4-seed1 spheres-3375-seed1
        spheres-125-seed1 spheres-512-seed1 spheres-1000-seed1 spheres-8000-seed1
        polyhedra-125-seed1 polyhedra-512-seed1 polyhedra-1000-seed1 polyhedra-3375-seed1
        spheres-125-seed2 spheres-125-seed3 spheres-512-seed2 spheres-512-seed3
        spheres-1000-seed2 spheres-1000-seed3)
else
  echo "study.sh: SET: expected paper or small, got '$set_name'" >&2
  exit 2
fi

status_of() {  # /run@status of a run file, or "none"
  [ -f "$1" ] || { echo none; return; }
  HDF5_USE_FILE_LOCKING=FALSE /usr/bin/python3 -c \
    'import sys, h5py; print(h5py.File(sys.argv[1], "r")["run"].attrs["status"])' "$1" 2>/dev/null || echo unreadable
}

mkdir -p "$out/runs" "$out/scenes"
for run in "${runs[@]}"; do
  scene=${run%-seed*}
  seed=${run##*-seed}
  src="$here/$scene.toml"
  if [ ! -f "$src" ] || ! [[ "$seed" =~ ^[0-9]+$ ]]; then
    echo "study.sh: $run: expected SCENE-seedK with SCENE.toml in $here" >&2
    exit 2
  fi
  dir="$out/runs/$run"
  status=$(status_of "$dir/run.h5")
  case "$status" in
    at_rest | end_time)
      echo "$run: done ($status)"
      continue
      ;;
    none) ;;
    *)
      echo "$run: $status: going on from its newest checkpoint"
      OMP_NUM_THREADS="$threads" "$rubble" run --resume "$dir" --until end_time --end-time "$end_time" -q
      continue
      ;;
  esac
  # The scene with its seed and a snapshot a minute (ten in the window).
  sed -e "s/^seed = .*/seed = $seed/" -e 's/^directory = .*/&\nsnapshot_interval = 60.0/' "$src" > "$out/scenes/$run.toml"
  grep -q "^seed = $seed$" "$out/scenes/$run.toml" || { echo "study.sh: cannot set the seed of $run" >&2; exit 1; }
  echo "$run: running to t = $end_time s ..."
  OMP_NUM_THREADS="$threads" "$rubble" run "$out/scenes/$run.toml" --out "$dir" --until end_time --end-time "$end_time" -q
done

[ "${POST:-1}" = 0 ] && exit 0
"$rubble" post --study "$out/runs" -o "$out/study" --stable-after "$window" -q
cat "$out/study/study.txt"
if [ -n "${FIGURES_DIR:-}" ]; then
  for png in "$out"/study/study_*.png; do
    name=$(basename "$png" .png)
    cp "$png" "$FIGURES_DIR/accretion-study-${name#study_}.png"
  done
fi
