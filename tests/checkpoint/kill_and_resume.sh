#!/usr/bin/env bash
# Restart is bit-identical (issue 8, item 2): runs SCENE once without interruption, then runs it
# again killing `rubble run` with SIGKILL at random points (three times, each after at least one
# checkpoint exists), resuming with `rubble run --resume` each time, and checks that the final
# state's hash and the run file (every step once, same values, same snapshots) equal the
# uninterrupted run's.
#
# usage: kill_and_resume.sh RUBBLE SCENE WORKDIR      (RUBBLE_KILL_SEED=N repeats a sequence)
set -euo pipefail
rubble=$1 scene=$2 work=$3
here=$(cd "$(dirname "$0")" && pwd)
export OMP_NUM_THREADS=2  # same thread count for every run (determinism is per thread count)
rm -rf "$work" && mkdir -p "$work"

seed=${RUBBLE_KILL_SEED:-$(( $(date +%s%N) % 32768 ))}
RANDOM=$seed
echo "kill_and_resume: random seed $seed (RUBBLE_KILL_SEED=$seed repeats this test)"

hash_of() { grep -o 'hash [0-9a-f]\{16\}' "$1" | awk '{print $2}'; }
now_ms() { echo $(( $(date +%s%N) / 1000000 )); }

t0=$(now_ms)
"$rubble" run "$scene" --out "$work/reference" -q > "$work/reference.log"
reference_ms=$(( $(now_ms) - t0 ))
reference_hash=$(hash_of "$work/reference.log")
echo "kill_and_resume: uninterrupted run: hash $reference_hash in ${reference_ms} ms"

run_dir="$work/killed"
options=(--checkpoint-every 100 -q)
for round in 1 2 3; do
  if [ "$round" = 1 ]; then
    "$rubble" run "$scene" --out "$run_dir" "${options[@]}" > "$work/round$round.log" 2>&1 &
  else
    "$rubble" run --resume "$run_dir" "${options[@]}" > "$work/round$round.log" 2>&1 &
  fi
  pid=$!
  # Kill only once a checkpoint exists (before it there is nothing to resume: a plain rerun).
  for _ in $(seq 1 6000); do
    if ls "$run_dir/checkpoints/"step-*.ckpt > /dev/null 2>&1 || ! kill -0 "$pid" 2> /dev/null; then break; fi
    sleep 0.01
  done
  delay_ms=$(( RANDOM % (reference_ms / 3 + 1) ))
  sleep "$(printf '%d.%03d' $(( delay_ms / 1000 )) $(( delay_ms % 1000 )))"
  if kill -KILL "$pid" 2> /dev/null; then
    wait "$pid" || true
    newest=$(ls "$run_dir/checkpoints/" | tail -1)
    echo "kill_and_resume: round $round: SIGKILL after ${delay_ms} ms; newest checkpoint $newest"
  else
    wait "$pid" || true
    echo "kill_and_resume: round $round: the run ended before the kill (${delay_ms} ms)"
  fi
done

"$rubble" run --resume "$run_dir" "${options[@]}" > "$work/final.log"
final_hash=$(hash_of "$work/final.log")
echo "kill_and_resume: resumed run: hash $final_hash"
if [ "$final_hash" != "$reference_hash" ]; then
  echo "kill_and_resume: FAILED: final state differs from the uninterrupted run's"
  exit 1
fi
/usr/bin/python3 "$here/compare_runs.py" "$work/reference/run.h5" "$run_dir/run.h5"
echo "kill_and_resume: 1 passed, 0 failed"
