"""Checks that two run files describe the same run, step for step (used by the restart tests).

usage: compare_runs.py REFERENCE.h5 RESUMED.h5

The series must hold every step exactly once, in order (1..N), and every column but the wall
times must be bitwise equal; the snapshots must be at the same steps with bitwise equal states and
contact impulses. Exit 0 if so, 1 with the first difference otherwise.
"""
import sys

import h5py
import numpy as np


def main(reference_path, resumed_path):
    with h5py.File(reference_path, "r") as reference, h5py.File(resumed_path, "r") as resumed:
        steps = resumed["series/step"][:]
        expected = np.arange(1, len(reference["series/step"]) + 1)
        if not np.array_equal(steps, expected):
            duplicated = len(steps) - len(np.unique(steps))
            return f"series steps are not 1..{len(expected)} once each ({len(steps)} rows, {duplicated} duplicated)"
        for column in ("time", "kinetic_energy", "contacts", "active_contacts", "iterations", "residual"):
            if not np.array_equal(reference["series"][column][:], resumed["series"][column][:]):
                return f"series/{column} differs"
        names = list(reference["snapshots"])
        if names != list(resumed["snapshots"]):
            return f"snapshot names differ: {names[-3:]} vs {list(resumed['snapshots'])[-3:]}"
        for name in names:
            a, b = reference["snapshots"][name], resumed["snapshots"][name]
            if a.attrs["step"] != b.attrs["step"]:
                return f"snapshot {name}: step {a.attrs['step']} vs {b.attrs['step']}"
            for dataset in ("position", "orientation", "velocity", "angular_velocity", "contact_impulse"):
                if not np.array_equal(a[dataset][:], b[dataset][:]):
                    return f"snapshot {name}/{dataset} differs"
    return None


if __name__ == "__main__":
    problem = main(sys.argv[1], sys.argv[2])
    if problem:
        print(f"compare_runs: {sys.argv[2]} vs {sys.argv[1]}: {problem}")
        sys.exit(1)
    print(f"compare_runs: {sys.argv[2]} matches {sys.argv[1]} step for step")
