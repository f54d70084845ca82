#!/usr/bin/env python3
"""Python module overhead: a Python loop of sim.step() against `rubble run` on the same scene.

usage: PYTHONPATH=BUILD/python /usr/bin/python3 bench/python/step_loop.py BUILD/apps/rubble [STEPS] [REPEATS]

The default accretion (1 000 spheres, Barnes-Hut self-gravity, dt = "auto") for STEPS steps
(default 1000), one OpenMP thread, REPEATS rounds (default 3), each round running, one after the
other:
  cli     `rubble run --end-time STEPS*dt -q`: process CPU (user + system, the child's rusage),
          which includes parsing the scene and writing run.h5 and checkpoints;
  loop    Simulation(default_scene()) then `for _ in range(STEPS): sim.step()`: CPU of this process
          over construction + loop (time.process_time);
  record  the same loop writing run.h5 as the CLI does (sim.record) and a checkpoint at the end;
  batch   sim.step(STEPS): one call, the loop in C++ (the Python overhead per step is loop - batch).
The best (least) CPU of the rounds is reported for each, per step, with the final state hashes
(all four must agree). Prints one markdown table for bench/RESULTS.md.
"""
import os
import resource
import subprocess
import sys
import tempfile
import time

import rubble


def cli_cpu(exe, steps, dt, folder):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    out = subprocess.run([exe, "run", "--end-time", repr(steps * dt), "-q", "--out", folder,
                          "--checkpoint-minutes", "0"], capture_output=True, text=True, check=True,
                         env=dict(os.environ, OMP_NUM_THREADS="1"))
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    hash_line = [line for line in out.stdout.splitlines() if "final state" in line][0]
    return cpu, wall, int(hash_line.split("hash ")[1].split(",")[0], 16)


def python_cpu(mode, steps, folder):
    start_cpu, start = time.process_time(), time.perf_counter()
    sim = rubble.Simulation(rubble.default_scene())
    if mode == "batch":
        sim.step(steps)
    else:
        if mode == "record":
            sim.record(folder, end_time=steps * sim.dt)
        step = sim.step
        for _ in range(steps):
            step()
        if mode == "record":
            sim.close()
            sim.save_checkpoint(os.path.join(folder, "checkpoints"))
    return time.process_time() - start_cpu, time.perf_counter() - start, sim.state_hash()


def main():
    exe = sys.argv[1]
    steps = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    if os.environ.get("OMP_NUM_THREADS") != "1":
        sys.exit("run with OMP_NUM_THREADS=1 (the CLI is run with one thread too)")
    dt = rubble.default_scene().dt
    best = {}
    hashes = set()
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeats):
            for mode in ("cli", "loop", "record", "batch"):
                folder = os.path.join(tmp, f"{mode}-{r}")
                if mode == "cli":
                    cpu, wall, h = cli_cpu(exe, steps, dt, folder)
                else:
                    cpu, wall, h = python_cpu(mode, steps, folder)
                hashes.add(h)
                print(f"round {r} {mode:6s} CPU {cpu:7.3f} s  wall {wall:7.3f} s  hash {h:016x}", file=sys.stderr)
                if mode not in best or cpu < best[mode][0]:
                    best[mode] = (cpu, wall)
    if len(hashes) != 1:
        sys.exit(f"final states differ: {sorted(hashes)}")
    load = open("/proc/loadavg").read().split()[:3]
    print(f"default accretion (1 000 spheres), {steps} steps, OMP_NUM_THREADS=1, best CPU of {repeats} rounds, "
          f"load average after: {' '.join(load)}; final state hash {hashes.pop():016x} for all")
    print()
    print("| run | CPU (s) | CPU per step (ms) | vs `rubble run` |")
    print("| --- | --- | --- | --- |")
    base = best["cli"][0]
    names = {"cli": "`rubble run` (parse, steps, run.h5, checkpoint)", "loop": "Python loop of `sim.step()`",
             "record": "Python loop of `sim.step()` + `sim.record` (run.h5) + checkpoint",
             "batch": "`sim.step(STEPS)` (one call)"}
    for mode in ("cli", "loop", "record", "batch"):
        cpu = best[mode][0]
        print(f"| {names[mode].replace('STEPS', str(steps))} | {cpu:.3f} | {1e3 * cpu / steps:.3f} | "
              f"{100 * (cpu / base - 1):+.1f} % |")
    # The call overhead itself, where a step costs almost nothing: one sphere in free flight.
    tiny = rubble.scene_from_dict({"time": {"dt": 1e-3, "end_time": 1.0}, "gravity": {"type": "none"},
                                   "materials": [{"name": "m", "density": 1000.0}],
                                   "default_contact_law": {"friction": 0.0},
                                   "bodies": [{"shape": "sphere", "radius": 0.1, "position": [0, 0, 0]}]})
    n = 20000
    loop_best = batch_best = float("inf")
    for _ in range(repeats):
        sim = rubble.Simulation(tiny)
        start = time.process_time()
        for _ in range(n):
            sim.step()
        loop_best = min(loop_best, time.process_time() - start)
        sim = rubble.Simulation(tiny)
        start = time.process_time()
        sim.step(n)
        batch_best = min(batch_best, time.process_time() - start)
    print()
    print(f"Per-call overhead, one free sphere, {n} steps: Python loop {1e6 * loop_best / n:.2f} µs a step, "
          f"one call sim.step({n}) {1e6 * batch_best / n:.2f} µs a step: {1e6 * (loop_best - batch_best) / n:.2f} µs "
          f"a call of sim.step() (the pybind11 call, the GIL release and the signal check), "
          f"{100 * (loop_best - batch_best) / n / (best['loop'][0] / steps):.3f} % of a default-accretion step")


if __name__ == "__main__":
    main()
