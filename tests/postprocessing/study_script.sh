#!/usr/bin/env bash
# examples/accretion/study.sh end to end on its small set: 125 spheres and 125 polyhedra (seed 1)
# to t = 2400 s, window from 1800 s (past the peak of <E_c>; a few CPU seconds each). Checks that
# the script makes both runs, that `rubble post --study` includes both (they ran to their end
# time and reached the window) with their window means, that the figures exist when
# /usr/bin/python3 has matplotlib, and that a second call keeps the finished runs (does not run
# them again) and redraws the study.
#
#   study_script.sh RUBBLE STUDY_SH WORK_DIR
set -euo pipefail
rubble=$1
study_sh=$2
work=$3
rm -rf "$work"
mkdir -p "$work"
SET=small END_TIME=2400 WINDOW=1800 bash "$study_sh" "$rubble" "$work/out" > "$work/first.log" 2>&1 ||
  { cat "$work/first.log"; echo "FAILED: study.sh (first call)"; exit 1; }
run=$work/out/runs/spheres-125-seed1/run.h5
before=$(stat -c %Y.%s "$run")
SET=small END_TIME=2400 WINDOW=1800 bash "$study_sh" "$rubble" "$work/out" > "$work/second.log" 2>&1 ||
  { cat "$work/second.log"; echo "FAILED: study.sh (second call)"; exit 1; }
[ "$(stat -c %Y.%s "$run")" = "$before" ] || { echo "FAILED: the second call ran spheres-125-seed1 again"; exit 1; }
grep -q "spheres-125-seed1: done (end_time)" "$work/second.log" ||
  { cat "$work/second.log"; echo "FAILED: the second call does not say the run is done"; exit 1; }
/usr/bin/python3 - "$work/out/study" <<'PYEOF'
import csv, importlib.util, os, sys
study = sys.argv[1]
with open(os.path.join(study, "study.csv"), newline="") as f:
    rows = {os.path.basename(os.path.dirname(r["run"])): r for r in csv.DictReader(f)}
failed = []
if sorted(rows) != ["polyhedra-125-seed1", "spheres-125-seed1"]:
    failed.append(f"study.csv runs: {sorted(rows)}")
for name, row in rows.items():
    if not (row["status"] == "end_time" and row["reached_window"] == "1" and row["included"] == "1"
            and row["averaged_over"] == "window" and int(row["snapshots_used"]) >= 10):
        failed.append(f"{name}: expected ended at its end time, in the window, included, 10 snapshots "
                      f"or more (1800 to 2400 s, one a minute): {row}")
    # At 30-40 min the spheres have collapsed (peak at 12 min), the polyhedra are collapsing (33 min).
    if row["grains"] != "125" or not 0.5 < float(row["Z_max"]) < 7.0:
        failed.append(f"{name}: grains {row['grains']}, Z {row['Z_max']}")
if importlib.util.find_spec("matplotlib") is not None:
    for png in ("study_kinetic_energy.png", "study_coordination.png", "study_diameter.png", "study_packing.png"):
        path = os.path.join(study, png)
        if not (os.path.isfile(path) and os.path.getsize(path) > 0):
            failed.append(f"{png} missing or empty")
for message in failed:
    print("FAILED:", message)
print(f"{'FAILED' if failed else 'passed'}: study.sh on the small set")
sys.exit(1 if failed else 0)
PYEOF
