#!/usr/bin/env bash
# Checkpoint retention and restart from an earlier step (issue 17): with [output]
# keep_checkpoint_every = 100 and a checkpoint every 50 steps, a 500-step run keeps the newest two
# and the first checkpoint of every 100 steps; `rubble run --resume DIR --from-step 200` sets the
# later ones aside, cuts run.h5 back to step 200 and ends in the uninterrupted run's state with
# every step once in the series; a step with no checkpoint is refused (exit 2, listing the steps).
#
# usage: restart_from_step.sh RUBBLE SCENE WORKDIR
set -u
rubble=$1 scene=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
fail() {
  echo "restart_from_step: FAILED: $*"
  for log in "$work"/*.log; do echo "--- $log"; head -c 2000 "$log"; done
  exit 1
}
export OMP_NUM_THREADS=1
{ cat "$scene"; printf '\n[output]\nkeep_checkpoint_every = 100\n'; } > "$work/scene.toml"
hash_of() { grep -o 'hash [0-9a-f]\{16\}' "$1" | awk '{print $2}'; }

"$rubble" run "$work/scene.toml" --out "$work/run" --checkpoint-every 50 -q > "$work/first.log" 2>&1 || fail "first run"
kept=$(ls "$work/run/checkpoints" | sed 's/step-0*\([0-9]*\)\.ckpt/\1/' | sort -n | tr '\n' ' ')
[ "$kept" = "50 100 200 300 400 450 500 " ] || fail "checkpoints kept: '$kept', expected '50 100 200 300 400 450 500 '"
echo "restart_from_step: kept checkpoints at steps $kept"

"$rubble" run --resume "$work/run" --from-step 123 > "$work/missing.log" 2>&1
code=$?
[ "$code" = 2 ] || fail "--from-step of a missing checkpoint: exit $code, expected 2"
grep -qF "no checkpoint of that step" "$work/missing.log" || fail "no message for a missing step"

"$rubble" run --resume "$work/run" --from-step 200 -q > "$work/resume.log" 2>&1 || fail "resume from step 200"
grep -qF "set aside" "$work/resume.log" || fail "no note of the checkpoints set aside"
[ "$(hash_of "$work/resume.log")" = "$(hash_of "$work/first.log")" ] ||
  fail "restart from step 200 ends at $(hash_of "$work/resume.log"), the uninterrupted run at $(hash_of "$work/first.log")"
/usr/bin/python3 - "$work/run/run.h5" << 'PY' || fail "run.h5 does not hold every step once"
import sys
import h5py
import numpy as np
with h5py.File(sys.argv[1], "r") as f:
    steps = f["series/step"][:]
assert np.array_equal(steps, np.arange(1, 501)), (steps[:3], steps[-3:], len(steps))
PY
echo "restart_from_step: restarted from step 200 to the same final state; 3 passed, 0 failed"
