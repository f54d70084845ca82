#!/usr/bin/python3
"""End-to-end test of `rubble post` on a short run (a CTest test).

Usage: test_post_command.py RUBBLE SCENE POSTPROCESSING.md OUTPUT-FORMAT.md CHECK_RUN_FILE.py WORKDIR

1. `rubble run SCENE` (27 spheres falling into a box, 0.4 s) writes WORKDIR/run/run.h5; its layout
   is checked against docs/output-format.md (check_run_file.py in layout-only mode).
2. `rubble post RUN --vtk` must write every file that docs/postprocessing.md lists for it (but the
   figures marked "aggregate only": the scene is a deposit); PNGs are PNGs, metrics.csv has
   exactly the documented columns and one row per snapshot, metrics.h5 holds the same numbers, the
   energy balance is sane (total energy never grows under uniform gravity with dissipative
   contacts, to 1e-6 relative).
3. `rubble post --study` on two copies of the run (which ended at its end time, not at rest, long
   before the 7500 s window) refuses them with exit code 2 and says both; with
   --include-unfinished it writes every study file the document lists, with the runs' status in
   study.csv, the window not replaced (their final snapshot, flagged) and 4 significant digits.
4. Plots without matplotlib (`--python` naming a program that has none) are a warning: exit 0,
   the CSV files written. A run file held open for writing (HDF5's file lock, as by a running
   `rubble run`) is read with a note instead of failing on the lock.
5. Bad input: a missing run file exits with code 2 and names the file.
Prints 'N passed, N failed' and exits non-zero on any failure.
"""
import csv
import os
import re
import shutil
import subprocess
import sys

import h5py
import numpy as np

passed, failed = 0, 0


def check(condition, message):
    global passed, failed
    if condition:
        passed += 1
    else:
        failed += 1
        print("FAILED:", message)


def documented_files(doc, section_title):
    """File names in the first column of the tables under a '## ' section."""
    names, inside = [], False
    for line in doc.splitlines():
        if line.startswith("## "):
            inside = line.strip() == section_title
            continue
        match = re.match(r"^\| `([\w./-]+)` \|", line)
        if inside and match:
            names.append(match.group(1))
    return names


def aggregate_only(doc, section_title):
    """Files of a section whose content cell starts with 'aggregate only'."""
    names, inside = [], False
    for line in doc.splitlines():
        if line.startswith("## "):
            inside = line.strip() == section_title
            continue
        match = re.match(r"^\| `([\w./-]+)` \| aggregate only", line)
        if inside and match:
            names.append(match.group(1))
    return names


def run(command, **kwargs):
    print("$", " ".join(command), flush=True)
    return subprocess.run(command, capture_output=True, text=True, **kwargs)


def main():
    rubble, scene, post_doc_path, format_doc, checker, work = sys.argv[1:7]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    with open(post_doc_path, encoding="utf-8") as f:
        post_doc = f.read()

    result = run([rubble, "run", scene, "-o", os.path.join(work, "run"), "-q"])
    check(result.returncode == 0, f"rubble run failed: {result.stderr}")
    run_file = os.path.join(work, "run", "run.h5")
    result = run(["/usr/bin/python3", checker, run_file, "-", format_doc])
    print(result.stdout, end="")
    check(result.returncode == 0, "the run file of `rubble run` does not match docs/output-format.md")

    with h5py.File(run_file, "r") as h5:
        kinds = set(int(k) for k in h5["/model/body_shape_kind"][()])
    not_applicable = set()  # ParaView files the model has no use for (documented as such)
    if 0 not in kinds:
        not_applicable.add("vtk/spheres.pvd")
    if 1 not in kinds:
        not_applicable.add("vtk/polyhedra.pvd")
    if not kinds & {2, 3}:
        not_applicable.add("vtk/walls.pvd")
    deposit_only = aggregate_only(post_doc, "## Files written by `rubble post RUN.h5`")
    check(deposit_only == ["packing_fraction.png", "aggregate_diameter.png"], f"aggregate-only figures: {deposit_only}")
    not_applicable.update(deposit_only)  # the scene is a deposit under uniform gravity

    out = os.path.join(work, "post")
    result = run([rubble, "post", run_file, "--vtk", "-o", out])
    check(result.returncode == 0, f"rubble post failed: {result.stdout} {result.stderr}")
    names = documented_files(post_doc, "## Files written by `rubble post RUN.h5`")
    check(len(names) >= 13, f"only {len(names)} files documented for rubble post")
    for name in names:
        path = os.path.join(out, name)
        if name in not_applicable:
            check(not os.path.exists(path), f"{path} written for a model without such bodies")
            continue
        check(os.path.isfile(path) and os.path.getsize(path) > 0, f"{path} missing or empty")
        if name.endswith(".png") and os.path.isfile(path):
            with open(path, "rb") as f:
                check(f.read(8) == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG")

    with h5py.File(run_file, "r") as h5:
        snapshots = len(h5["/snapshots"])
        grains = int(h5["/model"].attrs["grain_count"])
    with open(os.path.join(out, "metrics.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    columns = documented_files(post_doc, "## `metrics.csv` columns")
    check(rows and list(rows[0].keys()) == columns, "metrics.csv columns differ from docs/postprocessing.md")
    check(len(rows) == snapshots, f"metrics.csv has {len(rows)} rows for {snapshots} snapshots")
    check(all(int(float(r["grains"])) == grains for r in rows), "grain count")
    total = np.array([float(r["total_energy"]) for r in rows])
    check(np.all(np.diff(total) <= 1e-6 * np.abs(total).max()), f"total energy grows: {total}")
    check(max(float(r["coordination"]) for r in rows) > 0, "no contact ever in the deposit")
    with h5py.File(os.path.join(out, "metrics.h5"), "r") as h5:
        check(h5.attrs["format"] == "rubble-metrics", "metrics.h5 format attribute")
        for column in columns:
            values = h5["/metrics/" + column][()]
            check(np.array_equal(values, [float(r[column]) for r in rows]), f"metrics.h5 {column} differs from the CSV")

    study_runs = os.path.join(work, "study-runs")
    for k in (1, 2):
        os.makedirs(os.path.join(study_runs, f"run{k}"))
        shutil.copy(run_file, os.path.join(study_runs, f"run{k}", "run.h5"))
    shutil.copy(os.path.join(out, "metrics.h5"), os.path.join(study_runs, "run1"))  # not a run file: skipped
    study_out = os.path.join(work, "study")
    result = run([rubble, "post", "--study", study_runs, "-o", study_out, "-q"])
    # Runs to their end time are not cut short; these are left out for the window alone.
    check(result.returncode == 2 and "did not end at rest" not in result.stderr
          and "did not reach the window t >= 7500 s" in result.stderr,
          f"rubble post --study on runs to their end time, short of the window: code {result.returncode}, "
          f"{result.stderr}")
    result = run([rubble, "post", "--study", study_runs, "-o", study_out, "--include-unfinished", "-q"])
    check(result.returncode == 0, f"rubble post --study --include-unfinished failed: {result.stdout} {result.stderr}")
    for name in documented_files(post_doc, "## Files written by `rubble post --study`"):
        path = os.path.join(study_out, name)
        check(os.path.isfile(path) and os.path.getsize(path) > 0, f"{path} missing or empty")
    with open(os.path.join(study_out, "study.csv"), newline="") as f:
        study = list(csv.DictReader(f))
    check(len(study) == 2 and all(int(float(r["grains"])) == grains for r in study), "study.csv rows")
    check(all(r["status"] == "end_time" and r["included"] == "1" for r in study), f"study.csv status: {study}")
    # The window (7500 s) is not replaced by the run's last quarter: the final snapshot, flagged.
    check(all(r["reached_window"] == "0" and r["averaged_over"] == "final_snapshot" and r["snapshots_used"] == "1"
              for r in study), f"study.csv window: {study}")
    # 4 significant digits at most (17 before), e.g. the peak energy and D_max.
    for r in study:
        for key in ("peak_mean_kinetic_energy", "D_max", "Z_max"):
            digits = re.sub(r"e[-+]\d+$", "", r[key]).replace("-", "").replace(".", "").lstrip("0")
            check(len(digits) <= 4, f"study.csv {key} = {r[key]}: more than 4 significant digits")

    no_plots_out = os.path.join(work, "post-no-matplotlib")
    result = run([rubble, "post", run_file, "-o", no_plots_out, "--python", os.path.join(work, "no-such-python")])
    check(result.returncode == 0 and "warning: plots not drawn: no Python with matplotlib" in result.stderr,
          f"plots without matplotlib: code {result.returncode}, {result.stderr}")
    check(os.path.isfile(os.path.join(no_plots_out, "metrics.csv")), "metrics.csv not written without matplotlib")
    check(not os.path.exists(os.path.join(no_plots_out, "kinetic_energy.png")), "a PNG without matplotlib?")

    with h5py.File(run_file, "a"):  # holds HDF5's write lock, as a running `rubble run` does
        result = run([rubble, "post", run_file, "-o", os.path.join(work, "post-live"), "--no-plots", "-q"])
    check(result.returncode == 0 and "reading a run in progress" in result.stderr,
          f"run file held for writing: code {result.returncode}, {result.stderr}")

    missing = os.path.join(work, "no-such-run.h5")
    result = run([rubble, "post", missing, "-q"])
    check(result.returncode == 2 and missing in result.stderr, f"missing file: code {result.returncode}, {result.stderr}")

    print(f"{passed} passed, {failed} failed")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
