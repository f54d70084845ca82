#!/usr/bin/python3
"""Regenerates the speed-vs-accuracy charts of docs/accuracy-vs-speed.md.

    /usr/bin/python3 bench/solver/charts.py [--build DIR] [--quick]

Needs a build tree with `rubble` and `bench_fclib` (default: build-bench, configured and built
here if missing). Runs, in order:
  1. FCLib problems (shared/fclib): error reached vs sweeps and vs wall time, for the plain NLGS,
     over-relaxed NLGS (omega = 1.6) and NLGS + Levenberg-Marquardt polish -> docs/solver-fclib.png
  2. an accretion snapshot (3 375 self-gravitating grains after the collapse, see the doc): NLGS
     tolerance vs residual, interpenetration, wall time -> docs/solver-tolerance-accretion.png
  3. time step h vs energy error, interpenetration and wall time on the same snapshot and on a
     resting stack of spheres -> docs/solver-timestep.png
Raw figures go to bench/solver/*.csv. The gravity chart is docs/gravity-error-vs-time.png from
bench/gravity/run.sh.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
OUT = os.path.join(ROOT, "bench", "solver")
DOCS = os.path.join(ROOT, "docs")
FCLIB = os.path.abspath(os.path.join(ROOT, "..", "shared", "fclib"))
FILES = ["Box_Stacks-i0122-82-5_local.hdf5", "Capsules-i125-1213.hdf5", "Spheres-i099-356-679_local.hdf5",
         "fclib_local_problem_test_BoxesStack.hdf5"]
WORK = os.path.join("/tmp", "rubble-solver-charts")
G = 6.674e-11
# The accretion snapshot's grid: CELLS^3 grains (the study's 3 375-grain cloud).
CELLS = 15
GRAINS = CELLS**3


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw).stdout


def build(build_dir):
    rubble = os.path.join(build_dir, "apps", "rubble")
    bench = os.path.join(build_dir, "bench", "solver", "bench_fclib")
    if not (os.path.exists(rubble) and os.path.exists(bench)):
        run(["cmake", "-S", ROOT, "-B", build_dir, "-DCMAKE_BUILD_TYPE=Release"])
        run(["cmake", "--build", build_dir, "--target", "rubble", "bench_fclib", "-j2"])
    return rubble, bench


# ---------------------------------------------------------------- 1. FCLib
METHODS = {"NLGS": ["--polish", "none"], "NLGS, omega 1.6": ["--polish", "none", "--omega", "1.6"],
           "NLGS + LM polish": ["--polish", "newton"]}


def fclib_chart(bench, quick):
    rows = []
    caps = [10, 30, 100, 300, 1000, 3000, 10000] + ([] if quick else [30000, 100000])
    for name, extra in METHODS.items():
        for f in FILES:
            for cap in caps:
                line = run([bench, os.path.join(FCLIB, f), "--tolerances", "1e-10", "--max-iterations", str(cap),
                            "--reps", "2", "--polish-after", "20"] + extra)
                d = json.loads(line)
                d["method"] = name
                d["cap"] = cap
                rows.append(d)
                if d["converged"]:
                    break
    with open(os.path.join(OUT, "fclib_sweep.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["file", "method", "cap", "iterations", "newton_iterations", "error",
                                           "seconds", "converged"], extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    fig, axes = plt.subplots(2, 4, figsize=(16, 7))
    for j, f in enumerate(FILES):
        for name in METHODS:
            pts = sorted([r for r in rows if r["file"] == f and r["method"] == name], key=lambda r: r["cap"])
            err = [r["error"] if r["error"] is not None else np.nan for r in pts]
            axes[0, j].loglog([r["iterations"] for r in pts], err, "o-", label=name)
            axes[1, j].loglog([1e3 * r["seconds"] for r in pts], err, "o-", label=name)
        title = f.replace("_local", "").replace(".hdf5", "")
        axes[0, j].set_title(title, fontsize=9)
        axes[0, j].set_xlabel("sweeps (cap)")
        axes[1, j].set_xlabel("wall time (ms)")
        for i in range(2):
            axes[i, j].axhline(1e-8, color="grey", lw=0.5)
            axes[i, j].axhline(1e-4, color="grey", lw=0.5, ls="--")
            axes[i, j].set_ylabel("FCLib error |F|/|q|")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("FCLib problems: error reached vs sweeps and wall time (rubble default: 1e-4 in the simulation; "
                 "NLGS + LM polish for 1e-8)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(DOCS, "solver-fclib.png"), dpi=90)
    plt.close(fig)


# ---------------------------------------------------------------- scenes
def write_scene(path, name, dt, end_time, tolerance, max_iterations, body_lines, gravity, friction, walls="",
                snapshot_interval=None, restitution=0.0, density=5164.0):
    with open(path, "w") as fh:
        fh.write(f'name = "{name}"\nseed = 1\n\n[time]\ndt = {dt!r}\nend_time = {end_time!r}\n\n')
        fh.write(f"[solver]\ntolerance = {tolerance!r}\nmax_iterations = {max_iterations}\n\n")
        fh.write(gravity + "\n")
        fh.write(f'[output]\ndirectory = "out"\nsnapshot_interval = {snapshot_interval or end_time!r}\n\n')
        fh.write(f'[[materials]]\nname = "grain"\ndensity = {density!r}\n\n')
        fh.write(f'[[contact_laws]]\nmaterials = ["grain", "grain"]\nfriction = {friction!r}\n'
                 f"restitution = {restitution!r}\n\n")
        fh.write(walls)
        fh.write(body_lines)


def run_scene(rubble, scene, out_dir):
    start = time.perf_counter()
    run([rubble, "run", scene, "--out", out_dir, "--quiet"])
    return time.perf_counter() - start


def read_run(out_dir):
    f = h5py.File(os.path.join(out_dir, "run.h5"), "r")
    series = {k: f["series"][k][()] for k in ("time", "kinetic_energy", "residual", "iterations", "wall_seconds")}
    snaps = []
    for key in sorted(f["snapshots"].keys()):
        s = f["snapshots"][key]
        snaps.append({"time": s.attrs.get("time", 0.0), "position": s["position"][()], "velocity": s["velocity"][()],
                      "angular_velocity": s["angular_velocity"][()], "gap": s["contact_gap"][()]})
    model = {"mass": f["model"]["mass"][()], "radius": f["model"]["radius"][()],
             "inertia": f["model"]["principal_inertia"][()]}
    return series, snaps, model


def bodies_toml(model, snap):
    lines = []
    for b in np.nonzero(model["radius"] > 0)[0]:
        p, v, w = snap["position"][b], snap["velocity"][b], snap["angular_velocity"][b]
        lines.append(f'[[bodies]]\nshape = "sphere"\nradius = {model["radius"][b]!r}\n'
                     f"position = [{p[0]!r}, {p[1]!r}, {p[2]!r}]\nvelocity = [{v[0]!r}, {v[1]!r}, {v[2]!r}]\n"
                     f"angular_velocity = [{w[0]!r}, {w[1]!r}, {w[2]!r}]\n")
    return "\n".join(lines)


def gravitational_energy(model, position):
    m = model["mass"]
    grains = m > 0
    x, m = position[grains], m[grains]
    d = np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(-1))
    np.fill_diagonal(d, np.inf)
    return -0.5 * G * (m[:, None] * m[None, :] / d).sum()


def kinetic_energy(model, snap):
    m = model["mass"]
    grains = m > 0
    # Spheres: isotropic inertia, so the world-frame angular velocity needs no rotation.
    return 0.5 * (m[grains] * (snap["velocity"][grains] ** 2).sum(1)).sum() + \
        0.5 * (model["inertia"][grains, 0] * (snap["angular_velocity"][grains] ** 2).sum(1)).sum()


def max_overlap(snaps, model):
    worst = 0.0
    for s in snaps:
        if len(s["gap"]):
            worst = max(worst, -s["gap"].min())
    return worst / np.mean(model["radius"][model["radius"] > 0])


TREE = '[gravity]\ntype = "tree"\nG = 6.674e-11\ntheta = 0.5\norder = 2\n'


def accretion_snapshot(rubble, quick):
    """GRAINS grains (CELLS^3) of the accretion study's cloud, run through the collapse; the last
    state is the snapshot the other runs start from."""
    scene = os.path.join(WORK, f"accretion-{GRAINS}.toml")
    n = CELLS
    with open(scene, "w") as fh:
        end_time = 900.0 if quick else 1500.0
        fh.write(f'name = "accretion-{GRAINS}"\nseed = 1\n\n[time]\ndt = 0.5\nend_time = {end_time!r}\n\n')
        fh.write(TREE + '\n[output]\ndirectory = "out"\nsnapshot_interval = 100.0\n\n')
        fh.write('[[materials]]\nname = "grain"\ndensity = 5164.0\n\n'
                 '[[contact_laws]]\nmaterials = ["grain", "grain"]\nfriction = 0.0\nrestitution = 0.0\n\n')
        fh.write(f'[[generators]]\ntype = "cubic_grid"\ncells_per_side = {n}\nradius_min = 3.75\nradius_max = 5.0\n'
                 'distribution = "uniform_volume_fraction"\n')
    out = os.path.join(WORK, f"accretion-{GRAINS}")
    seconds = run_scene(rubble, scene, out)
    series, snaps, model = read_run(out)
    return model, snaps[-1], seconds


def tolerance_chart(rubble, model, snap, quick):
    bodies = bodies_toml(model, snap)
    rows = []
    window, dt = 100.0, 0.5
    for tol in [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6] + ([] if quick else [1e-7]):
        scene = os.path.join(WORK, f"tol-{tol:g}.toml")
        write_scene(scene, f"accretion-{GRAINS}-snapshot", dt, window, tol, 10000, bodies, TREE, 0.0,
                    snapshot_interval=5.0)
        out = os.path.join(WORK, f"tol-{tol:g}")
        run_scene(rubble, scene, out)
        series, snaps, m = read_run(out)
        rows.append({"tolerance": tol, "mean_residual": float(np.mean(series["residual"])),
                     "max_residual": float(np.max(series["residual"])),
                     "mean_sweeps": float(np.mean(series["iterations"])),
                     "overlap": max_overlap(snaps, m), "wall_seconds": float(np.sum(series["wall_seconds"]))})
    with open(os.path.join(OUT, "tolerance_accretion.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    tol = [r["tolerance"] for r in rows]
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    ax[0].loglog(tol, [r["mean_residual"] for r in rows], "o-", label="mean over steps")
    ax[0].loglog(tol, [r["max_residual"] for r in rows], "s--", label="worst step")
    ax[0].loglog(tol, tol, "k:", lw=0.8, label="= tolerance")
    ax[0].set_ylabel("NLGS residual at exit")
    ax[0].legend(fontsize=8)
    ax[1].semilogx(tol, [100 * r["overlap"] for r in rows], "o-")
    ax[1].set_ylabel("max interpenetration (% of mean radius)")
    ax[2].semilogx(tol, [r["wall_seconds"] for r in rows], "o-")
    ax2 = ax[2].twinx()
    ax2.semilogx(tol, [r["mean_sweeps"] for r in rows], "s--", color="C1")
    ax2.set_ylabel("mean sweeps per step", color="C1")
    ax[2].set_ylabel("wall time of the window (s)")
    for a in ax:
        a.set_xlabel("NLGS tolerance")
        a.axvline(1e-4, color="grey", lw=0.8, ls="--")
    fig.suptitle(f"Accretion snapshot ({GRAINS} grains after collapse, {window:g} s at h = {dt} s, tree gravity): "
                 "rubble default tolerance 1e-4 (dashed)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(DOCS, "solver-tolerance-accretion.png"), dpi=90)
    plt.close(fig)
    return rows


def stack_scene(path, dt, end_time, snapshot_interval):
    """Ten spheres of 5 cm stacked in a square tube of their diameter under 1 g, from rest."""
    r = 0.05
    walls = ""
    for point, normal in [([0, 0, 0], [0, 0, 1]), ([-r, 0, 0], [1, 0, 0]), ([r, 0, 0], [-1, 0, 0]),
                          ([0, -r, 0], [0, 1, 0]), ([0, r, 0], [0, -1, 0])]:
        walls += f'[[walls]]\ntype = "plane"\npoint = {point}\nnormal = {normal}\n\n'
    bodies = "\n".join(f'[[bodies]]\nshape = "sphere"\nradius = {r}\nposition = [0.0, 0.0, {r * (2 * k + 1)!r}]\n'
                       for k in range(10))
    write_scene(path, "stack", dt, end_time, 1e-6, 1000, bodies,
                '[gravity]\ntype = "uniform"\nacceleration = [0.0, 0.0, -9.81]\n', 0.3, walls=walls,
                snapshot_interval=snapshot_interval, density=2500.0)


def timestep_chart(rubble, model, snap, quick):
    bodies = bodies_toml(model, snap)
    window = 100.0
    acc = []
    steps = [4.0, 2.0, 1.0, 0.5, 0.25] + ([] if quick else [0.125])
    for dt in steps:
        scene = os.path.join(WORK, f"dt-{dt:g}.toml")
        write_scene(scene, f"accretion-{GRAINS}-snapshot", dt, window, 1e-4, 1000, bodies, TREE, 0.0,
                    snapshot_interval=max(dt, 5.0))
        out = os.path.join(WORK, f"dt-{dt:g}")
        run_scene(rubble, scene, out)
        series, snaps, m = read_run(out)
        e0 = kinetic_energy(m, snaps[0]) + gravitational_energy(m, snaps[0]["position"])
        e1 = kinetic_energy(m, snaps[-1]) + gravitational_energy(m, snaps[-1]["position"])
        acc.append({"dt": dt, "energy_end": e1, "energy_start": e0, "overlap": max_overlap(snaps, m),
                    "wall_seconds": float(np.sum(series["wall_seconds"]))})
    reference = acc[-1]["energy_end"]
    for a in acc:
        a["energy_error"] = abs(a["energy_end"] - reference) / abs(reference)
    stack = []
    for dt in [1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4] + ([] if quick else [1e-4]):
        scene = os.path.join(WORK, f"stack-{dt:g}.toml")
        stack_scene(scene, dt, 1.0, max(dt, 0.01))
        out = os.path.join(WORK, f"stack-{dt:g}")
        run_scene(rubble, scene, out)
        series, snaps, m = read_run(out)
        grains = m["mass"] > 0
        energy = [kinetic_energy(m, s) + 9.81 * (m["mass"][grains] * s["position"][grains, 2]).sum() for s in snaps]
        scale = 9.81 * (m["mass"][grains] * snaps[0]["position"][grains, 2]).sum()
        stack.append({"dt": dt, "energy_error": max(abs(e - energy[0]) for e in energy) / scale,
                      "overlap": max_overlap(snaps, m), "wall_seconds": float(np.sum(series["wall_seconds"]))})
    for name, rows in (("timestep_accretion.csv", acc), ("timestep_stack.csv", stack)):
        with open(os.path.join(OUT, name), "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    fig, ax = plt.subplots(2, 3, figsize=(14, 7))
    for i, (rows, label, default) in enumerate(((acc, f"accretion snapshot ({GRAINS} grains, 100 s)", 0.5),
                                                 (stack, "stack of 10 spheres at rest (1 s)", 1e-4))):
        h = [r["dt"] for r in rows]
        # The accretion reference (smallest h) has no error of its own: left out of the log plot.
        shown = rows[:-1] if i == 0 else rows
        ax[i, 0].loglog([r["dt"] for r in shown], [r["energy_error"] for r in shown], "o-")
        ax[i, 0].set_ylabel("energy error" + (" vs smallest h" if i == 0 else " (max drift / m g z)"))
        ax[i, 1].semilogx(h, [100 * r["overlap"] for r in rows], "o-")
        ax[i, 1].set_ylabel("max interpenetration (% of radius)")
        ax[i, 2].loglog(h, [r["wall_seconds"] for r in rows], "o-")
        ax[i, 2].set_ylabel("wall time (s)")
        for a in ax[i]:
            a.set_xlabel("time step h (s)")
            a.axvline(default, color="grey", ls="--", lw=0.8)
            a.set_title(label, fontsize=9)
    fig.suptitle("Time step vs energy error, interpenetration and wall time (dashed: the default h of the "
                 "examples: 0.5 s for accretion, 1e-4 s for deposits)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(DOCS, "solver-timestep.png"), dpi=90)
    plt.close(fig)
    return acc, stack


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", default=os.path.join(ROOT, "build-bench"))
    parser.add_argument("--quick", action="store_true", help="fewer points (a smoke run)")
    parser.add_argument("--only", choices=["fclib", "scenes"], help="run one part")
    args = parser.parse_args()
    rubble, bench = build(args.build)
    os.makedirs(WORK, exist_ok=True)
    if args.only in (None, "fclib"):
        fclib_chart(bench, args.quick)
        print("docs/solver-fclib.png", flush=True)
    if args.only in (None, "scenes"):
        model, snap, seconds = accretion_snapshot(rubble, args.quick)
        print(f"accretion snapshot: {seconds:.1f} s", flush=True)
        tolerance_chart(rubble, model, snap, args.quick)
        print("docs/solver-tolerance-accretion.png", flush=True)
        timestep_chart(rubble, model, snap, args.quick)
        print("docs/solver-timestep.png", flush=True)


if __name__ == "__main__":
    sys.exit(main())
