#!/usr/bin/env python3
"""One accretion run for bench/RESULTS.md: time to rest (simulated, wall, CPU), steps/s, the
mean kinetic energy's peak, contacts, NLGS iterations and the wall-time split per stage, from the
run file's /series (docs/output-format.md).
Usage: summarize.py RUN.h5 LABEL WALL_S USER_S SYSTEM_S"""
import sys

import h5py
import numpy as np


def main(path, label, wall, user, system):
    with h5py.File(path, "r") as f:
        s = f["series"]
        steps = len(s["time"])
        t = s["time"][:]
        grains = int(np.sum(f["model/mass"][:] > 0))
        ke = s["kinetic_energy"][:] / grains
        step_wall = float(np.sum(s["wall_seconds"][:]))
        stages = {name: float(np.sum(s["stage_seconds"][name][:])) for name in s["stage_seconds"]}
    h = (t[-1] - t[0]) / max(steps - 1, 1)
    print(f"### {label}")
    print(f"- grains {grains}, dt = {h:.4g} s (auto), {steps} steps to t = {t[-1]:.0f} s ({t[-1] / 60:.0f} min); "
          f"mean kinetic energy per grain: peak {ke.max():.3g} J at t = {t[np.argmax(ke)]:.0f} s, final {ke[-1]:.3g} J")
    print(f"- wall {float(wall):.0f} s, CPU user {float(user):.0f} s + system {float(system):.0f} s; "
          f"**{steps / step_wall:.1f} steps/s** ({1e3 * step_wall / steps:.1f} ms/step of stepping)")
    print(f"- contacts: final {int(s_last(path, 'contacts'))}; NLGS iterations: mean {mean_of(path, 'iterations'):.1f}")
    print("- time per stage: " + ", ".join(
        f"{k} {100 * v / step_wall:.0f}%" for k, v in sorted(stages.items(), key=lambda kv: -kv[1])))
    print()


def s_last(path, column):
    with h5py.File(path, "r") as f:
        return f["series"][column][-1]


def mean_of(path, column):
    with h5py.File(path, "r") as f:
        return float(np.mean(f["series"][column][:]))


if __name__ == "__main__":
    main(*sys.argv[1:6])
