#!/usr/bin/env python3
"""Prints the figures of a run file for bench/RESULTS.md: steps/s, contacts, NLGS iterations,
residual and the wall-time split per stage (from /series, docs/output-format.md)."""
import sys

import h5py
import numpy as np


def summarize(path, label):
    with h5py.File(path, "r") as f:
        s = f["series"]
        wall = s["wall_seconds"][:]
        steps = len(wall)
        stages = {name: float(np.sum(s["stage_seconds"][name][:])) for name in s["stage_seconds"]}
        grains = int(np.sum(f["model/mass"][:] > 0))
        total = float(np.sum(wall))
        print(f"### {label}")
        print(f"- grains {grains}, steps {steps}, wall {total:.2f} s, **{steps / total:.1f} steps/s**, "
              f"{1e3 * total / steps:.2f} ms/step")
        print(f"- contacts: mean {np.mean(s['contacts'][:]):.0f}, final {int(s['contacts'][-1])}; "
              f"NLGS iterations: mean {np.mean(s['iterations'][:]):.1f}, max {int(np.max(s['iterations'][:]))}; "
              f"residual: median {np.median(s['residual'][:]):.1e}, max {np.max(s['residual'][:]):.1e}")
        print("- time per stage: " + ", ".join(
            f"{k} {100 * v / total:.0f}% ({1e3 * v / steps:.3f} ms)" for k, v in stages.items()))
        print()


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        path, _, label = arg.partition("=")
        summarize(path, label or path)
