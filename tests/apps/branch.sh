#!/usr/bin/env bash
# Continuation with changes (issue 18): a run that ended at rest goes on with --resume and a later
# --end-time (not stopping again after one step), --until end_time runs to the end time; a branch
# `rubble run SCENE --from DIR` with another friction and dt starts from DIR's last state bit for
# bit; bodies that differ are refused (exit 2, naming what differs); the snapshot and time
# selectors; `rubble export` writes a scene whose state is the snapshot's, bit for bit, and which
# runs to rest.
#
# usage: branch.sh RUBBLE SCENE WORKDIR
set -u
rubble=$1 scene=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
fail() {
  echo "branch: FAILED: $*"
  for log in "$work"/*.log; do echo "--- $log"; head -c 3000 "$log"; done
  exit 1
}
export OMP_NUM_THREADS=1
py=/usr/bin/python3

# A: the deposit until at rest.
"$rubble" run "$scene" --out "$work/a" > "$work/a.log" 2>&1 || fail "run A"
grep -q "rubble run: at rest at t = " "$work/a.log" || fail "A did not stop at rest"
$py - "$work/a/run.h5" << 'PY' || fail "A's /run"
import sys, h5py
with h5py.File(sys.argv[1], "r") as f:
    run = f["run"]
    assert run.attrs["status"] == "at_rest", run.attrs["status"]
    assert run.attrs["stop_reason"].startswith("at rest at t = "), run.attrs["stop_reason"]
    for name in ["rest_speed", "rest_quantile", "rest_coordination_change", "rest_contact_change", "rest_duration"]:
        assert name in run, name
    assert run["rest_quantile"][()] == 0.99
PY
a_end=$(sed -n 's/.*done: \([0-9]*\) steps.*/\1/p' "$work/a.log")

# Resumed from a checkpoint inside the quiet window, the run stops at rest on the same step in
# the same state (the watcher's window, reference Z and contacts are in the checkpoint).
hash_of() { grep -o 'hash [0-9a-f]\{16\}' "$1" | awk '{print $2}'; }
sed -e 's/^snapshot_every_steps = 20$/snapshot_every_steps = 20\nkeep_checkpoint_every = 20/' "$scene" > "$work/k.toml"
"$rubble" run "$work/k.toml" --out "$work/k" --checkpoint-every 20 -q > "$work/k.log" 2>&1 || fail "run K"
k_from=$(( (a_end - 30) / 20 * 20 ))
"$rubble" run --resume "$work/k" --from-step "$k_from" -q > "$work/k-resume.log" 2>&1 || fail "resume K from $k_from"
[ "$(hash_of "$work/k-resume.log")" = "$(hash_of "$work/a.log")" ] ||
  fail "resumed at step $k_from inside the rest window: ends at $(hash_of "$work/k-resume.log"), the uninterrupted run at $(hash_of "$work/a.log")"

# Resumed after rest with a later end: a new quiet window of rest_duration (0.1 s = 50 steps), not
# one step; with --until end_time it runs to the end time.
cp -r "$work/a" "$work/a2"
"$rubble" run --resume "$work/a2" --end-time 3.0 > "$work/resume.log" 2>&1 || fail "resume after rest"
steps=$(sed -n 's/.*done: \([0-9]*\) steps.*/\1/p' "$work/resume.log")
[ "$steps" -ge 50 ] || fail "the resumed run took $steps steps after rest, expected >= 50 (a new window of 0.1 s)"
grep -q "starts a new window" "$work/resume.log" || fail "no note that the rest watcher starts a new window"
"$rubble" run --resume "$work/a2" --end-time 2.0 --until end_time -q > "$work/resume-end.log" 2>&1 ||
  fail "resume with --until end_time"
$py - "$work/a2/run.h5" << 'PY' || fail "the run resumed with --until end_time did not reach t = 2 s"
import sys, h5py
with h5py.File(sys.argv[1], "r") as f:
    assert f["run"].attrs["status"] == "end_time", f["run"].attrs["status"]
    t = f["series/time"][-1]
    assert abs(t - 2.0) < 1e-9, t
PY
"$rubble" run --resume "$work/a2" --end-time 2.5 --rest-speed 0.5 --rest-duration 0.05 -q > "$work/resume-rest.log" 2>&1 ||
  fail "resume with --rest-speed"
$py - "$work/a2/run.h5" << 'PY' || fail "--rest-speed on resume not recorded or not used"
import sys, h5py
with h5py.File(sys.argv[1], "r") as f:
    run = f["run"]
    assert run["rest_speed"][()] == 0.5 and run["rest_speed"].attrs["source"] == "scene", run["rest_speed"][()]
    assert run["rest_duration"][()] == 0.05
    assert run.attrs["status"] == "at_rest", run.attrs["status"]
    t = f["series/time"][-1]
    assert 2.05 - 1e-9 <= t < 2.1, t  # a new window of 0.05 s (25 steps) after t = 2 s
PY

# B: a branch from A's last state with friction 0.6 and dt 0.001.
sed -e 's/^friction = 0.3$/friction = 0.6/' -e 's/^dt = 0.002$/dt = 0.001/' -e 's/^until = "rest"$/until = "end_time"/' \
    -e '/^rest_duration/d' -e 's/^end_time = 3.0$/end_time = 1.5/' "$scene" > "$work/b.toml"
[ "$(grep -c -e '^friction = 0.6$' -e '^dt = 0.001$' "$work/b.toml")" = 2 ] || fail "cannot edit $scene"
"$rubble" run "$work/b.toml" --from "$work/a" --out "$work/b" > "$work/b.log" 2>&1 || fail "branch B"
grep -q "branching from checkpoint" "$work/b.log" || fail "B does not say where it branched from"
$py - "$work/a/run.h5" "$work/b/run.h5" << 'PY' || fail "B's first state is not A's last"
import sys, h5py
with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as b:
    last = a["snapshots"][sorted(a["snapshots"])[-1]]
    first = b["snapshots"][sorted(b["snapshots"])[0]]
    for key in ["position", "orientation", "velocity", "angular_velocity"]:
        assert last[key][:].tobytes() == first[key][:].tobytes(), key
    assert last.attrs["time"] == first.attrs["time"] and last.attrs["step"] == first.attrs["step"]
    assert b["model/contact_laws/friction"][0, 0] == 0.6
    assert b["run/time_step"][()] == 0.001
    assert b["run"].attrs["status"] == "end_time"
    assert abs(b["series/time"][-1] - 1.5) < 1e-9
PY
# S: the same branch with [[initial_conditions]]: the saved state, plus a rigid spin about the
# grains' centre of mass added to every grain's velocity (walls untouched).
{ cat "$work/b.toml"; printf '\n[[initial_conditions]]\nangular_velocity = [0.0, 0.0, 0.5]\n'; } > "$work/s.toml"
"$rubble" run "$work/s.toml" --from "$work/a" --out "$work/s" -q > "$work/s.log" 2>&1 || fail "branch S with a spin"
$py - "$work/a/run.h5" "$work/s/run.h5" << 'PY' || fail "S's first state is not A's last plus the spin"
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as s:
    last = a["snapshots"][sorted(a["snapshots"])[-1]]
    first = s["snapshots"][sorted(s["snapshots"])[0]]
    mass = a["model/mass"][:]
    grain = mass > 0
    x = last["position"][:][grain]
    centre = (mass[grain, None] * x).sum(axis=0) / mass[grain].sum()
    omega = np.array([0.0, 0.0, 0.5])
    expected = last["velocity"][:].copy()
    expected[grain] += np.cross(omega, x - centre)
    assert np.abs(first["velocity"][:] - expected).max() < 1e-12, np.abs(first["velocity"][:] - expected).max()
    w = last["angular_velocity"][:].copy()
    w[grain] += omega
    assert np.abs(first["angular_velocity"][:] - w).max() < 1e-15
    assert first["position"][:].tobytes() == last["position"][:].tobytes()
PY
# From a snapshot and from a time: the state of that snapshot.
"$rubble" run "$work/b.toml" --from "$work/a:snapshot=3" --out "$work/b3" -q > "$work/b3.log" 2>&1 || fail "--from :snapshot=3"
"$rubble" run "$work/b.toml" --from "$work/a/run.h5:time=0.13" --out "$work/bt" -q > "$work/bt.log" 2>&1 ||
  fail "--from :time=0.13"
$py - "$work/a/run.h5" "$work/b3/run.h5" "$work/bt/run.h5" << 'PY' || fail "snapshot or time selector"
import sys, h5py
with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as b3, h5py.File(sys.argv[3], "r") as bt:
    s3 = a["snapshots"][sorted(a["snapshots"])[3]]
    first = b3["snapshots"][sorted(b3["snapshots"])[0]]
    assert s3["position"][:].tobytes() == first["position"][:].tobytes()
    assert s3["velocity"][:].tobytes() == first["velocity"][:].tobytes()
    # time=0.13: the last snapshot at or before 0.13 s, snapshot 3 (t = 0.12 s; snapshots every 0.04 s).
    first_t = bt["snapshots"][sorted(bt["snapshots"])[0]]
    assert abs(first_t.attrs["time"] - 0.12) < 1e-9, first_t.attrs["time"]
    assert s3["angular_velocity"][:].tobytes() == first_t["angular_velocity"][:].tobytes()
PY
# Bodies that differ: exit 2, naming the difference.
sed -e 's/^cells_per_side = 3$/cells_per_side = 2/' "$work/b.toml" > "$work/c.toml"
"$rubble" run "$work/c.toml" --from "$work/a" --out "$work/c" > "$work/c.log" 2>&1
code=$?
[ "$code" = 2 ] || fail "branch with other bodies: exit $code, expected 2"
grep -qF "the scene has 13 bodies (8 grains), the saved run 32 bodies (27 grains)" "$work/c.log" ||
  fail "no message naming the body counts"
"$rubble" run "$work/b.toml" --from "$work/a:snapshot=999" --out "$work/c" > "$work/c2.log" 2>&1
code=$?
[ "$code" = 2 ] || fail "--from a missing snapshot: exit $code, expected 2"
grep -qF "no snapshot 999" "$work/c2.log" || fail "no message for a missing snapshot"

# Export: the last snapshot as a scene; its first snapshot (zero steps) is that state, bit for bit.
"$rubble" export "$work/a/run.h5" -o "$work/exported.toml" > "$work/export.log" 2>&1 || fail "rubble export"
grep -q '^until = "rest"$' "$work/exported.toml" || fail "the exported scene lost until = rest"
"$rubble" run "$work/exported.toml" --out "$work/e0" --end-time 0.002 -q > "$work/e0.log" 2>&1 || fail "run the export"
$py - "$work/a/run.h5" "$work/e0/run.h5" << 'PY' || fail "the exported scene's state is not the snapshot's"
import sys, h5py
with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as e:
    last = a["snapshots"][sorted(a["snapshots"])[-1]]
    first = e["snapshots"][sorted(e["snapshots"])[0]]
    for key in ["position", "orientation", "velocity", "angular_velocity"]:
        assert last[key][:].tobytes() == first[key][:].tobytes(), key
    assert first.attrs["time"] == 0.0 and first.attrs["step"] == 0
    assert e["run/time_step"][()] == a["run/time_step"][()]
    assert e["run/rest_speed"][()] == a["run/rest_speed"][()]
PY
# The exported scene runs on to rest (its grains move: the rest watcher starts armed).
"$rubble" run "$work/exported.toml" --out "$work/e" > "$work/e.log" 2>&1 || fail "run the exported scene"
grep -q "rubble run: at rest at t = " "$work/e.log" || fail "the exported scene did not come to rest"
echo "branch: A at rest after $a_end steps; resume, branch, spin, selectors, mismatch and export checked"
