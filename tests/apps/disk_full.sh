#!/usr/bin/env bash
# A full disk (issue 17), on a small tmpfs: `rubble run` stops with exit code 4 and a message
# naming the file and "No space left on device", without crashing (HDF5 used to SIGSEGV at exit);
# when the disk fills mid-run, the last checkpoint is intact, no partial temporary is left, and
# once space is freed `rubble run --resume` goes on (run.h5, damaged by the failed write, is moved
# aside and the series continues in a new run.h5) to the same final state as an uninterrupted run.
#
# Needs root (mount); otherwise it says so and exits 77, which CTest reports as skipped.
#
# usage: disk_full.sh RUBBLE SCENE WORKDIR GENERATED   (GENERATED: make_inputs.py's folder)
set -u
rubble=$1 scene=$2 work=$3 generated=$4
if [ "$(id -u)" != 0 ]; then
  echo "disk_full: SKIPPED: needs root to mount a small tmpfs"
  exit 77
fi
mkdir -p "$work"
disk=$work/disk
mkdir -p "$disk"
umount "$disk" 2> /dev/null
cleanup() { umount "$disk" 2> /dev/null; }
trap cleanup EXIT
if ! mount -t tmpfs -o size=64k tmpfs "$disk" 2> "$work/mount.log"; then
  echo "disk_full: SKIPPED: cannot mount a tmpfs here: $(cat "$work/mount.log")"
  exit 77
fi
fail() {
  echo "disk_full: FAILED: $*"
  for log in "$work"/*.log; do echo "--- $log"; head -c 3000 "$log"; done
  exit 1
}
no_crash() {
  if grep -qE "Segmentation fault|HDF5-DIAG|terminate called|Aborted" "$1"; then fail "crash or HDF5 error stack in $1"; fi
}
export OMP_NUM_THREADS=1

# 1. Full at the first write of run.h5 (64 KiB).
"$rubble" run "$scene" --out "$disk/run" -q > "$work/tiny.log" 2>&1
code=$?
[ "$code" = 4 ] || fail "disk full at the first write: exit $code, expected 4"
grep -qF "No space left on device" "$work/tiny.log" || fail "the message does not say the disk is full"
grep -qF "rubble run: output failure: writing the output failed at step" "$work/tiny.log" || fail "no output-failure message"
no_crash "$work/tiny.log"
echo "disk_full: full at the first write: exit 4, $(head -c 200 "$work/tiny.log")"

# 2. Full mid-run (400 KiB), with checkpoints every 200 steps.
umount "$disk" && mount -t tmpfs -o size=400k tmpfs "$disk" || fail "cannot remount"
options=(--end-time 2 --checkpoint-every 200 -q)
"$rubble" run "$scene" --out "$disk/run" "${options[@]}" > "$work/midrun.log" 2>&1
code=$?
[ "$code" = 4 ] || fail "disk full mid-run: exit $code, expected 4"
no_crash "$work/midrun.log"
step=$(grep -o 'the last checkpoint (step [0-9]*) is intact' "$work/midrun.log" | grep -o '[0-9]*')
[ -n "$step" ] || fail "the message does not name an intact checkpoint"
newest=$(ls "$disk/run/checkpoints/" | grep -v '\.tmp$' | tail -1)
[ "$newest" = "$(printf 'step-%012d.ckpt' "$step")" ] || fail "newest checkpoint $newest, the message says step $step"
if ls "$disk/run/checkpoints/" | grep -q '\.tmp$'; then fail "a partial .tmp checkpoint was left"; fi
echo "disk_full: full mid-run: exit 4, checkpoint of step $step intact"

# 3. Space freed: --resume goes on from that checkpoint (run.h5, damaged by the failed flush, is
# set aside) and ends in the state of an uninterrupted run, bit for bit.
mount -o remount,size=64m "$disk" || fail "cannot grow the tmpfs"
"$rubble" run --resume "$disk/run" "${options[@]}" > "$work/resume.log" 2>&1
code=$?
[ "$code" = 0 ] || fail "resume after freeing space: exit $code, expected 0"
no_crash "$work/resume.log"
"$rubble" run "$scene" --out "$work/reference" "${options[@]}" > "$work/reference.log" 2>&1 || fail "reference run"
hash_of() { grep -o 'hash [0-9a-f]\{16\}' "$1" | awk '{print $2}'; }
[ -n "$(hash_of "$work/reference.log")" ] || fail "no hash in the reference run's output"
[ "$(hash_of "$work/resume.log")" = "$(hash_of "$work/reference.log")" ] ||
  fail "resumed final state $(hash_of "$work/resume.log") differs from the uninterrupted run's $(hash_of "$work/reference.log")"
/usr/bin/python3 - "$disk/run/run.h5" "$step" << 'PY' || fail "the new run.h5 does not continue from the checkpoint"
import sys
import h5py
import numpy as np
with h5py.File(sys.argv[1], "r") as f:
    steps = f["series/step"][:]
    first = f["snapshots/000000"].attrs["step"]
k = int(sys.argv[2])
assert first == k, (first, k)
assert np.array_equal(steps, np.arange(k + 1, k + 1 + len(steps))), steps[:5]
print(f"new run.h5: first snapshot at step {first}, series rows {steps[0]}..{steps[-1]}")
PY
grep -qF "cannot be reopened" "$work/resume.log" || fail "no warning that run.h5 was set aside"
echo "disk_full: resumed after freeing space to hash $(hash_of "$work/resume.log") (= uninterrupted); 3 passed, 0 failed"

# 4. The other commands' outputs on a full disk: exit 4 naming the file, no crash, no exit 0.
umount "$disk" && mount -t tmpfs -o size=256k tmpfs "$disk" || fail "cannot remount"
dd if=/dev/zero of="$disk/filler" bs=4k 2> /dev/null  # until the disk is full
"$rubble" run "$scene" --out "$work/small" -q --end-time 0.01 > "$work/small.log" 2>&1 || fail "a small run for post"
"$rubble" post "$work/small/run.h5" --no-plots -q -o "$disk/post" > "$work/post_full.log" 2>&1
code=$?
[ "$code" = 4 ] || fail "rubble post onto a full disk: exit $code, expected 4"
grep -qF "rubble post: output failure:" "$work/post_full.log" || fail "rubble post: no output-failure message"
"$rubble" pack cubic-grid --n 8 --dmin 0.01 --dmax 0.02 --density 2500 -o "$disk/pack.toml" > "$work/pack_full.log" 2>&1
code=$?
[ "$code" = 4 ] || fail "rubble pack onto a full disk: exit $code, expected 4"
/usr/bin/python3 -c "
import h5py, numpy as np
with h5py.File('$work/particles.h5', 'w') as f:
    f['positions'] = np.random.default_rng(1).uniform(-1, 1, (2000, 3))
    f['masses'] = np.ones(2000)
" || fail "cannot make a particle file"
"$rubble" gravity "$work/particles.h5" --out "$disk/field.h5" > "$work/gravity_full.log" 2>&1
code=$?
[ "$code" = 4 ] || fail "rubble gravity onto a full disk: exit $code, expected 4"
"$rubble" fclib "$generated/fclib_good.hdf5" --out "$disk/solution.h5" > "$work/fclib_full.log" 2>&1
code=$?
[ "$code" = 4 ] || fail "rubble fclib onto a full disk: exit $code, expected 4"
for log in post_full pack_full gravity_full fclib_full; do no_crash "$work/$log.log"; done
echo "disk_full: post, pack, gravity and fclib onto a full disk: exit 4 each; 4 passed, 0 failed"
