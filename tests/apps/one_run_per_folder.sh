#!/usr/bin/env bash
# One run per output folder (issue 17), with real processes: while a first `rubble run` writes
# into DIR, a second `rubble run --out DIR` and a `rubble run --resume DIR` are refused with exit 2
# and a message naming the first run's pid, and touch nothing (run.h5 keeps its bytes while the
# first run is held by SIGSTOP): the first run goes on, stops on SIGTERM with its checkpoint, and
# its run.h5 holds every step once up to that checkpoint. Then a
# run killed with SIGKILL leaves its pid in DIR/rubble.lock; the next run takes the stale lock
# over (saying whose it was) and resumes.
#
# usage: one_run_per_folder.sh RUBBLE SCENE WORKDIR
set -u
rubble=$1 scene=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
out=$work/run
first=
fail() {
  echo "one_run_per_folder: FAILED: $*"
  # Do not leave the first run held (SIGSTOP below) or running after a failure.
  [ -n "$first" ] && kill -CONT "$first" 2> /dev/null && kill -TERM "$first" 2> /dev/null
  for log in "$work"/*.log; do echo "--- $log"; head -c 2000 "$log"; done
  exit 1
}
# Waits until PID owns DIR (its pid in the lock file) and a checkpoint exists.
wait_for_owner() {
  local pid=$1
  for _ in $(seq 1 3000); do
    if [ "$(cat "$out/rubble.lock" 2> /dev/null)" = "$pid" ] && ls "$out/checkpoints/"step-*.ckpt > /dev/null 2>&1; then
      return 0
    fi
    kill -0 "$pid" 2> /dev/null || fail "run $pid ended before the test could use it"
    sleep 0.01
  done
  fail "run $pid never took the lock"
}
# The newest checkpoint's file name (empty if none).
newest_checkpoint() { ls "$out/checkpoints/"step-*.ckpt 2> /dev/null | sort | tail -1; }
# Waits until PID has written a checkpoint newer than $2: it is stepping, past the reopen of
# run.h5 (a fixed sleep was not always enough on a loaded machine).
wait_for_new_checkpoint() {
  local pid=$1 before=$2
  for _ in $(seq 1 6000); do
    [ "$(newest_checkpoint)" != "$before" ] && return 0
    kill -0 "$pid" 2> /dev/null || fail "run $pid ended before writing a new checkpoint"
    sleep 0.01
  done
  fail "run $pid wrote no new checkpoint"
}
# Waits until the file $1 holds the text $2 (a message printed just after taking the lock).
wait_for_text() {
  for _ in $(seq 1 3000); do
    grep -qF "$2" "$1" && return 0
    sleep 0.01
  done
  return 1
}
# Every step once, 1..N, in run.h5's series, N = the newest checkpoint's step.
check_run_file() {
  /usr/bin/python3 - "$out" << 'EOF' || fail "run.h5 is not intact"
import glob, os, sys
import h5py
import numpy as np
out = sys.argv[1]
newest = max(int(os.path.basename(p)[5:17]) for p in glob.glob(f"{out}/checkpoints/step-*.ckpt"))
with h5py.File(f"{out}/run.h5", "r") as f:
    steps = f["series/step"][:]
print(f"run.h5: {len(steps)} series rows, newest checkpoint at step {newest}")
assert np.array_equal(steps, np.arange(1, newest + 1)), (steps[:5], steps[-5:], newest)
EOF
}

# 1. A second writer while the first runs.
"$rubble" run "$scene" --out "$out" --end-time 1000 --checkpoint-every 500 -q > "$work/first.log" 2>&1 &
first=$!
wait_for_owner "$first"
# The first run is held (SIGSTOP) while the others try: its own flushes may move run.h5's size
# either way (HDF5 truncates the file to its allocated end; a check without the hold failed once
# on a shrink of 1.5 kB), so with it held any change of the file is the refused runs' doing.
kill -STOP "$first"
size_before=$(stat -c %s "$out/run.h5")
sum_before=$(cksum < "$out/run.h5")
"$rubble" run "$scene" --out "$out" > "$work/second.log" 2>&1
code=$?
[ "$code" = 2 ] || fail "a second run into the same folder: exit $code, expected 2"
grep -qF "in use by another rubble run (pid $first;" "$work/second.log" || fail "the refusal does not name pid $first"
"$rubble" run --resume "$out" > "$work/resume_live.log" 2>&1
code=$?
[ "$code" = 2 ] || fail "--resume of a live folder: exit $code, expected 2"
grep -qF "(pid $first;" "$work/resume_live.log" || fail "the --resume refusal does not name pid $first"
kill -0 "$first" 2> /dev/null || fail "the first run died"
size_after=$(stat -c %s "$out/run.h5")
[ "$size_after" = "$size_before" ] || fail "run.h5 went from $size_before to $size_after bytes while its writer was held"
[ "$(cksum < "$out/run.h5")" = "$sum_before" ] || fail "run.h5's bytes changed while its writer was held"
kill -CONT "$first"
kill -TERM "$first"
wait "$first"
code=$?
[ "$code" = 143 ] || fail "the first run, stopped by SIGTERM: exit $code, expected 143"
[ ! -s "$out/rubble.lock" ] || fail "the lock file still names an owner after a clean stop"
check_run_file
echo "one_run_per_folder: a second writer and a --resume were refused (exit 2, pid $first named); the first run's output is intact"

# 2. A stale lock: the owner is SIGKILLed, its pid stays in the file.
before=$(newest_checkpoint)
"$rubble" run --resume "$out" --end-time 1000 --checkpoint-every 500 -q > "$work/killed.log" 2>&1 &
killed=$!
wait_for_owner "$killed"
wait_for_new_checkpoint "$killed" "$before"  # past the reopen of run.h5, into the stepping
kill -KILL "$killed"
wait "$killed"
[ "$(cat "$out/rubble.lock")" = "$killed" ] || fail "the lock file does not hold the killed run's pid $killed"
"$rubble" run --resume "$out" --end-time 1000 --checkpoint-every 500 > "$work/takeover.log" 2>&1 &
takeover=$!
wait_for_owner "$takeover"
wait_for_text "$work/takeover.log" "took over the stale lock of pid $killed" || fail "no note of the stale lock of pid $killed"
kill -TERM "$takeover"
wait "$takeover"
code=$?
[ "$code" = 143 ] || fail "the run that took over, stopped by SIGTERM: exit $code, expected 143"
check_run_file
echo "one_run_per_folder: the stale lock of SIGKILLed pid $killed was taken over; 2 passed, 0 failed"
