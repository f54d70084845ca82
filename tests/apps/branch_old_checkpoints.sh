#!/usr/bin/env bash
# `rubble run SCENE --from DIR` when DIR's checkpoints cannot be read (written by an older rubble,
# format version 2 here): the branch starts from the run file's last snapshot and says so; without
# a run file either, exit 2 with a message that names both.
#
# usage: branch_old_checkpoints.sh RUBBLE SCENE WORKDIR
set -u
rubble=$1 scene=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
fail() {
  echo "branch_old_checkpoints: FAILED: $*"
  for log in "$work"/*.log; do echo "--- $log"; head -c 3000 "$log"; done
  exit 1
}
export OMP_NUM_THREADS=1
py=/usr/bin/python3

"$rubble" run "$scene" --out "$work/a" -q > "$work/a.log" 2>&1 || fail "run A"
ls "$work"/a/checkpoints/*.ckpt > /dev/null 2>&1 || fail "A wrote no checkpoint"
# Format version 2 in every checkpoint's header (bytes 8-11, little-endian, after the magic).
for ckpt in "$work"/a/checkpoints/*.ckpt; do
  printf '\x02\x00\x00\x00' | dd of="$ckpt" bs=1 seek=8 conv=notrunc status=none || fail "patch $ckpt"
done

"$rubble" run "$scene" --from "$work/a" --out "$work/b" --end-time 0.06 > "$work/b.log" 2>&1 ||
  fail "the branch from a folder of old checkpoints: exit $?, expected 0 (the last snapshot)"
grep -q "checkpoint format version 2" "$work/b.log" || fail "B does not say why the checkpoint was not used"
grep -q "the run file's last snapshot is used instead" "$work/b.log" || fail "B does not say what it used"
$py - "$work/a/run.h5" "$work/b/run.h5" << 'PY' || fail "B's first state is not A's last snapshot"
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as b:
    last = sorted(a["snapshots"])[-1]
    for name in ["position", "orientation", "velocity", "angular_velocity"]:
        assert np.array_equal(a["snapshots"][last][name][:], b["snapshots/000000"][name][:]), name
PY

rm "$work/a/run.h5"
"$rubble" run "$scene" --from "$work/a" --out "$work/c" > "$work/c.log" 2>&1
code=$?
[ "$code" = 2 ] || fail "old checkpoints and no run file: exit $code, expected 2"
grep -q "checkpoint format version 2" "$work/c.log" || fail "C does not name the checkpoint's problem"
grep -q "no run file" "$work/c.log" || fail "C does not say that the run file is missing"
echo "branch_old_checkpoints: fallback to the last snapshot and the error without a run file checked"
