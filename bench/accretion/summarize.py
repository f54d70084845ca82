#!/usr/bin/env python3
"""One accretion run for bench/RESULTS.md: time to rest (simulated, wall, CPU), steps/s, the
mean kinetic energy's peak, contacts, NLGS sweeps per step over the run and the time split per
stage, from the run file's /series (docs/output-format.md) and the `/usr/bin/time -v` report.
A run stopped before rest (SIGINT at the time limit) is extrapolated to rest: the remaining
simulated time to the typical rest time REST_S (env, default 4000 s: the 1 000- and 3 375-sphere
runs rest at 4 187 s and 3 794 s) at the last tenth's CPU cost per simulated second.
Usage: summarize.py RUN.h5 LABEL TIME_V_FILE [LOAD_BEFORE] [LOAD_AFTER]"""
import os
import re
import sys

import h5py
import numpy as np


def time_report(path):
    """User, system (s), wall (s) and peak RSS (MB) from /usr/bin/time -v."""
    text = open(path).read()
    field = lambda key: re.search(re.escape(key) + r".*?:\s*(\S+)\s*$", text, re.M).group(1)
    wall = 0.0
    for part in field("Elapsed (wall clock) time").split(":"):
        wall = 60.0 * wall + float(part)
    return float(field("User time (seconds)")), float(field("System time (seconds)")), wall, \
        float(field("Maximum resident set size (kbytes)")) / 1024.0


def main(path, label, timev, load_before="?", load_after="?"):
    user, system, wall, rss = time_report(timev)
    cpu = user + system
    with h5py.File(path, "r") as f:
        s = f["series"]
        t = s["time"][:]
        sweeps = s["iterations"][:]
        contacts = s["contacts"][:]
        grains = int(np.sum(f["model/mass"][:] > 0))
        ke = s["kinetic_energy"][:] / grains
        step_wall = s["wall_seconds"][:]
        stages = {name: float(np.sum(s["stage_seconds"][name][:])) for name in s["stage_seconds"]}
        sweep_seconds = s["stage_seconds"]["nlgs_sweeps"][:]
    steps = len(t)
    h = (t[-1] - t[0]) / max(steps - 1, 1)
    log = open(os.path.join(os.path.dirname(os.path.dirname(path)), label + ".log")).read() \
        if os.path.exists(os.path.join(os.path.dirname(os.path.dirname(path)), label + ".log")) else ""
    at_rest = "at rest at t" in log
    print(f"### {label}")
    print(f"- grains {grains}, dt = {h:.4g} s (auto), {steps} steps to t = {t[-1]:.0f} s; "
          f"{'at rest' if at_rest else 'NOT at rest (stopped)'}; mean kinetic energy per grain: "
          f"peak {ke.max():.3g} J at t = {t[np.argmax(ke)]:.0f} s, final {ke[-1]:.3g} J")
    print(f"- CPU {cpu:.1f} s (user {user:.1f} + system {system:.1f}), wall {wall:.0f} s, peak RSS {rss:.0f} MB, "
          f"load average before {load_before} / after {load_after}; "
          f"{steps / cpu:.1f} steps per CPU second ({1e3 * cpu / steps:.2f} ms CPU/step, "
          f"{1e6 * cpu / steps / grains:.2f} µs per grain and step)")
    if not at_rest:
        rest = float(os.environ.get("REST_S", "4000"))
        tail = slice(int(0.9 * steps), steps)
        cpu_per_sim_s = cpu * float(np.sum(step_wall[tail]) / np.sum(step_wall)) / (t[tail][-1] - t[tail][0])
        print(f"- extrapolated: rest at t ≈ {rest:.0f} s → ≈ {cpu + max(rest - t[-1], 0) * cpu_per_sim_s:.0f} s CPU "
              f"(last tenth: {cpu_per_sim_s:.3f} CPU s per simulated s)")
    print(f"- contacts at the end {int(contacts[-1])}; NLGS sweeps per step: mean {sweeps.mean():.1f}, by eighths of the run "
          + ", ".join(f"{sweeps[k:k + max(steps // 8, 1)].mean():.1f}" for k in range(0, steps, max(steps // 8, 1)))
          + f"; sweep cost {1e9 * sweep_seconds.sum() / max(float(np.sum(sweeps * contacts)), 1):.0f} ns per sweep and contact")
    total = float(np.sum(step_wall))
    print("- time per stage (share of the stepping wall time): " + ", ".join(
        f"{k} {100 * v / total:.0f}%" for k, v in sorted(stages.items(), key=lambda kv: -kv[1])))
    print()


if __name__ == "__main__":
    main(*sys.argv[1:6])
