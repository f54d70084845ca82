#!/usr/bin/env bash
# SIGTERM and SIGINT stop `rubble run` cleanly (issue 8, item 2): the run writes a checkpoint,
# says so, and exits with 128 + the signal's number; resuming then ends in the uninterrupted
# run's state with the same run file.
#
# usage: signal_stop.sh RUBBLE SCENE WORKDIR
set -euo pipefail
rubble=$1 scene=$2 work=$3
here=$(cd "$(dirname "$0")" && pwd)
export OMP_NUM_THREADS=2
rm -rf "$work" && mkdir -p "$work"
hash_of() { grep -o 'hash [0-9a-f]\{16\}' "$1" | awk '{print $2}'; }

"$rubble" run "$scene" --out "$work/reference" -q > "$work/reference.log"
reference_hash=$(hash_of "$work/reference.log")

run_dir="$work/stopped"
# No checkpoint by step count or by time: the ones found below come from the signals.
options=(--checkpoint-minutes 0 -q)
stop_with() {  # stop_with SIGNAL EXPECTED_CODE LOG [rubble run arguments...]
  local signal=$1 expected=$2 log=$3
  shift 3
  "$rubble" run "$@" "${options[@]}" > "$log" 2>&1 &
  local pid=$!
  for _ in $(seq 1 6000); do
    if [ -e "$run_dir/run.h5" ] || ! kill -0 "$pid" 2> /dev/null; then break; fi
    sleep 0.01
  done
  sleep 0.3
  kill "-$signal" "$pid"
  local code=0
  wait "$pid" || code=$?
  if [ "$code" != "$expected" ]; then
    echo "signal_stop: FAILED: after SIG$signal the exit code is $code, expected $expected"; cat "$log"; exit 1
  fi
  if ! grep -q "stopped by SIG$signal at step [0-9]*.*checkpoint written" "$log"; then
    echo "signal_stop: FAILED: no 'stopped by SIG$signal ... checkpoint written' line"; cat "$log"; exit 1
  fi
  echo "signal_stop: $(grep 'stopped by' "$log")"
}
stop_with TERM 143 "$work/term.log" "$scene" --out "$run_dir"
# run.h5 says the run was interrupted, and its last snapshot is the state at the stop (marked
# @interrupted unless the stop fell on a step of the snapshot cadence).
stopped_step=$(grep -o 'stopped by SIGTERM at step [0-9]*' "$work/term.log" | awk '{print $NF}')
/usr/bin/python3 - "$run_dir/run.h5" "$stopped_step" << 'EOF'
import sys
import h5py
with h5py.File(sys.argv[1], "r") as f:
    step = int(sys.argv[2])
    last = f["snapshots"][sorted(f["snapshots"])[-1]]
    marked = 0 if step % int(f["run/snapshot_every_steps"][()]) == 0 else 1
    found = (f["run"].attrs["status"], int(last.attrs["step"]), int(last.attrs["interrupted"]), int(f["snapshot_step"][-1]))
    expected = ("interrupted", step, marked, step)
    if found != expected:
        sys.exit(f"signal_stop: FAILED: status, last snapshot step, @interrupted, /snapshot_step[-1] = {found}, "
                 f"expected {expected}")
    print(f"signal_stop: run.h5 status interrupted, last snapshot at step {step} (@interrupted = {marked})")
EOF
stop_with INT 130 "$work/int.log" --resume "$run_dir"
"$rubble" run --resume "$run_dir" "${options[@]}" > "$work/final.log"
if [ "$(hash_of "$work/final.log")" != "$reference_hash" ]; then
  echo "signal_stop: FAILED: final state differs from the uninterrupted run's"; exit 1
fi
/usr/bin/python3 "$here/compare_runs.py" "$work/reference/run.h5" "$run_dir/run.h5"
echo "signal_stop: 1 passed, 0 failed"
