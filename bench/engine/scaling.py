#!/usr/bin/env python3
"""Issue 9 scaling benchmark: single-thread CPU time per step against the number of grains N, for
box deposits of spheres and of random polyhedra, the fitted exponent (least squares of log t on
log N), docs/scaling.png, and the peak resident memory per grain at the largest N.

Each case is a box deposit (written here as a scene file): N grains of radius 4-6 cm (polyhedra:
circumscribed diameter 8-12 cm, 10-16 vertices), density 2500, mu = 0.5, e = 0, one per cell of a
12.4 cm grid, 8 layers deep in a square box (floor + 4 plane walls) whose width grows as sqrt(N),
so that every N has the same depth and the same contacts per grain.
1. Settling: the grains start moving down at 2 m/s under g = 9.81 and run SETTLE steps of
   dt = 5e-4 s (0.2 s: the top layer has fallen 0.6 m, the pile has landed and compacted, 2-3
   contact points per grain; a grain at 4 m/s moves 2 mm per step, the alert distance) with at most
   SETTLE_SWEEPS NLGS sweeps per step (100 for spheres, 400 for polyhedra) and the Newton polish
   off (polish_after = 0: its sparse factorisation dominates steps of landing grains; it is for the
   timed steps only). With the
   sweep order of the parallel solver, 39 sweeps left two of 10^4 spheres 1.3% of a radius into
   each other, more than the listed-scene loader accepts (1%); 100 sweeps leave 0.6%. With the
   relative residual, 100 sweeps left one of 3*10^4 polyhedra 0.49 mm (1.1% of its radius) behind
   the floor: polyhedra settle with up to 400.
   The deposit is compacting, not at rest, at the end (mean speed ~0.5 m/s at 10^4 spheres):
   the timed steps are those of a dense pile still rearranging, ~2 contact points per sphere.
2. The state at the end of the settling is written as a scene with every grain listed (as scene_to_toml does) and the
   benchmark's own settings: dt = 1e-4 s, NLGS tolerance 1e-4, up to 1000 sweeps (polish on), and
   run for WARMUP steps (warm start rebuilt; checkpoint at the end).
3. That run is resumed twice (`rubble run --resume`): for 1 step and for K steps; the CPU time per
   step is (CPU_K - CPU_1) / (K - 1) (user + sys of /usr/bin/time, OMP_NUM_THREADS=1), which removes
   the start-up cost (scene parse, checkpoint load).
The peak RSS per grain is (max RSS of the settling run - max RSS of a 1-grain run) / N: the settling
run reads the small generator scene; the listed scene's runs also hold its TOML document while
parsing it (their peak RSS is reported as well, "listed").

Usage: /usr/bin/python3 bench/engine/scaling.py BUILD_DIR [--work DIR] [--plot-only] [--quick]
"""
import argparse
import csv
import math
import os
import shutil
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DT = 5e-4        # s, settling
SETTLE = 400     # settling steps
SETTLE_SWEEPS = {"sphere": 100, "polyhedron": 400}  # NLGS sweeps per settling step at most (polish off)
DT_TIMED = 1e-4  # s, warm-up and timed steps
WARMUP = 20
PLURAL = {"sphere": "spheres", "polyhedron": "polyhedra"}
CELL = 0.124
LAYERS = 8
# (shape, N, timed steps K): fewer timed steps for the large N (the CPU budget of the sweep).
PLAN = [
    ("sphere", 1_000, 200), ("sphere", 3_000, 200), ("sphere", 10_000, 100), ("sphere", 30_000, 60),
    ("sphere", 100_000, 30),
    ("polyhedron", 1_000, 150), ("polyhedron", 3_000, 100), ("polyhedron", 10_000, 50),
    ("polyhedron", 30_000, 20),
]


def scene_text(shape, n):
    """A box deposit of n grains, LAYERS deep: cells per side k = ceil(sqrt(n / LAYERS))."""
    k = math.ceil(math.sqrt(n / LAYERS))
    half = 0.5 * k * CELL + 1e-3  # walls 1 mm outside the grid
    layers = math.ceil(n / (k * k))
    shape_keys = 'shape = "polyhedron"\nmin_vertices = 10\nmax_vertices = 16\n' if shape == "polyhedron" else ""
    walls = "".join(
        f'[[walls]]\ntype = "plane"\npoint = [{p[0]}, {p[1]}, 0.0]\nnormal = [{q[0]}, {q[1]}, {q[2]}]\n\n'
        for p, q in [((0.0, 0.0), (0, 0, 1)), ((-half, 0.0), (1, 0, 0)), ((half, 0.0), (-1, 0, 0)),
                     ((0.0, -half), (0, 1, 0)), ((0.0, half), (0, -1, 0))])
    return f'''name = "scaling-{shape}-{n}"
seed = 1
[time]
dt = {DT}
theta = 0.5
end_time = {SETTLE * DT!r}
[solver]
tolerance = 1e-4
max_iterations = {SETTLE_SWEEPS[shape]}
polish_after = 0
[gravity]
type = "uniform"
acceleration = [0.0, 0.0, -9.81]
[output]
directory = "scaling-output"
snapshot_interval = 1.0
progress_interval = 30.0
[[materials]]
name = "rock"
density = 2500.0
[default_contact_law]
friction = 0.5
restitution = 0.0
{walls}[[generators]]
type = "box_deposit"
{shape_keys}count = {n}
radius_min = 0.04
radius_max = 0.06
cell_size = {CELL}
region_min = [{-half}, {-half}, 0.0]
region_max = [{half}, {half}, {layers * CELL + 1e-3}]
velocity = [0.0, 0.0, -2.0]
'''


def timed(cmd, log):
    """Runs cmd under /usr/bin/time with one OpenMP thread: (CPU s = user + sys, wall s, max RSS kB)."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    tfile = log + ".time"
    with open(log, "w") as out:
        result = subprocess.run(["/usr/bin/time", "-f", "%U %S %e %M", "-o", tfile] + cmd, stdout=out,
                                stderr=subprocess.STDOUT, env=env)
    if result.returncode != 0:
        lines = open(log).read().strip().splitlines()
        raise RuntimeError(f"`{' '.join(os.path.basename(c) for c in cmd[:3])}` exited with {result.returncode}: "
                           f"{lines[-1] if lines else '(no output)'} (log {log})")
    u, s, e, m = open(tfile).read().split()[-4:]
    return float(u) + float(s), float(e), int(m)


def listed_scene(scene, run_h5, out):
    """The last snapshot of run_h5 as a scene with every grain listed (spheres by radius, polyhedra by
    body-frame vertices and faces, as scene_to_toml writes them), the header of `scene` (walls,
    materials, laws) with [time] and [solver] set for the timed steps."""
    import re
    import h5py
    text = open(scene).read()
    header = text[:text.index("[[generators]]")]
    header = re.sub(r"\[time\].*?(?=\n\[solver\])",
                    f"[time]\ndt = {DT_TIMED!r}\ntheta = 0.5\nend_time = {WARMUP * DT_TIMED!r}\n", header, count=1,
                    flags=re.S)
    header = re.sub(r"max_iterations = \d+\npolish_after = 0", "max_iterations = 1000", header, count=1)
    v3 = lambda a: "[" + ", ".join(repr(float(x)) for x in a) + "]"
    with h5py.File(run_h5, "r") as f:
        m = f["model"]
        kind, index, radius = m["body_shape_kind"][:], m["body_shape_index"][:], m["radius"][:]
        P = m["polyhedra"]
        verts, voff = P["vertices"][:], P["vertex_offset"][:]
        fv, foff, pfoff = P["face_vertices"][:], P["face_offset"][:], P["polyhedron_face_offset"][:]
        snap = f["snapshots"][sorted(f["snapshots"].keys())[-1]]
        pos, q, vel, omg = (snap[k][:] for k in ("position", "orientation", "velocity", "angular_velocity"))
    with open(out, "w") as o:
        o.write(header)
        for b in range(len(kind)):
            place = (f"position = {v3(pos[b])}\norientation = {v3(q[b])}\nvelocity = {v3(vel[b])}\n"
                     f"angular_velocity = {v3(omg[b])}\n")
            if kind[b] == 0:
                o.write(f'[[bodies]]\nshape = "sphere"\nradius = {float(radius[b])!r}\n{place}\n')
            elif kind[b] == 1:
                p = index[b]
                vs = ", ".join(v3(v) for v in verts[voff[p]:voff[p + 1]])
                faces = ", ".join("[" + ", ".join(str(int(i)) for i in fv[foff[k]:foff[k + 1]]) + "]"
                                  for k in range(pfoff[p], pfoff[p + 1]))
                o.write(f'[[bodies]]\nshape = "polyhedron"\n{place}convexity_tolerance = 0.05\n'
                        f"vertices = [{vs}]\nfaces = [{faces}]\n\n")


def run_case(rubble, work, shape, n, steps):
    import h5py
    d = os.path.join(work, f"{shape}-{n}")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    path = os.path.join(d, "scene.toml")
    with open(path, "w") as f:
        f.write(scene_text(shape, n))
    settling = os.path.join(d, "settling")
    cpu_settle, _, rss = timed([rubble, "run", path, "--out", settling, "-q"], settling + ".log")
    listed = os.path.join(d, "settled.toml")
    listed_scene(path, os.path.join(settling, "run.h5"), listed)
    shutil.rmtree(settling)
    settled = os.path.join(d, "settled")
    _, _, rss_listed = timed([rubble, "run", listed, "--out", settled, "-q"], settled + ".log")
    t_end = WARMUP * DT_TIMED
    cpus = {}
    for k in (1, steps):
        out = os.path.join(d, f"resume-{k}")
        shutil.copytree(settled, out)
        cpus[k], _, _ = timed([rubble, "run", "--resume", out, "--end-time", repr(t_end + k * DT_TIMED), "-q"],
                              out + ".log")
    with h5py.File(os.path.join(d, f"resume-{steps}", "run.h5"), "r") as f:
        s = f["series"]
        contacts = float(np.mean(s["contacts"][-steps:]))
        sweeps = float(np.mean(s["iterations"][-steps:]))
        residual = float(np.max(s["residual"][-steps:]))
        wall_ms = 1e3 * float(np.mean(s["wall_seconds"][-steps:]))
        order = [x.decode() if isinstance(x, bytes) else str(x) for x in s["stage_seconds"].attrs["stage_order"]]
        stages = {k: float(np.mean(s["stage_seconds"][k][-steps:])) for k in order}
    top = sorted(stages.items(), key=lambda kv: -kv[1])[:3]
    total = sum(stages.values())
    row = dict(shape=shape, n=n, steps=steps, cpu_ms=1e3 * (cpus[steps] - cpus[1]) / (steps - 1), wall_ms=wall_ms,
               contacts=contacts, sweeps=sweeps, residual_max=residual, settle_cpu_s=cpu_settle,
               startup_cpu_s=cpus[1], peak_rss_kb=rss, listed_rss_kb=rss_listed, load=open("/proc/loadavg").read().split()[0],
               top_stages="; ".join(f"{k} {100 * v / total:.0f}%" for k, v in top))
    shutil.rmtree(d)  # the run files of the large cases are big; the figures are in the CSV
    return row


def baseline_rss(rubble, work):
    """Peak RSS of a 1-grain run: what the binary, its libraries and the run file cost without grains."""
    d = os.path.join(work, "baseline")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    with open(os.path.join(d, "scene.toml"), "w") as f:
        f.write(scene_text("sphere", 1))
    _, _, rss = timed([rubble, "run", os.path.join(d, "scene.toml"), "--out", os.path.join(d, "out"), "-q"],
                      os.path.join(d, "log"))
    shutil.rmtree(d)
    return rss


def fit(rows, shape):
    x = np.log([r["n"] for r in rows if r["shape"] == shape])
    y = np.log([r["cpu_ms"] for r in rows if r["shape"] == shape])
    if len(x) < 2:
        return float("nan"), float("nan")
    slope, intercept = np.polyfit(x, y, 1)
    return float(slope), float(intercept)


def plot(rows, png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for shape, colour, marker in (("sphere", "tab:blue", "o"), ("polyhedron", "tab:red", "s")):
        pts = [r for r in rows if r["shape"] == shape]
        if not pts:
            continue
        n = np.array([r["n"] for r in pts], float)
        t = np.array([r["cpu_ms"] for r in pts], float)
        slope, intercept = fit(rows, shape)
        ax.loglog(n, t, marker, color=colour, label=f"{PLURAL[shape]} (CPU ms per step)")
        nn = np.geomspace(n.min(), n.max(), 50)
        ax.loglog(nn, np.exp(intercept) * nn ** slope, "-", color=colour, lw=1,
                  label=f"fit: t ∝ N^{slope:.2f}")
        ax.loglog(nn, t[0] * (nn / n[0]) ** 1.1, ":", color=colour, lw=1, label="N^1.1 from the first point")
    ax.set_xlabel("grains N")
    ax.set_ylabel("CPU time per step, one thread (ms)")
    ax.set_title("rubble: compacting box deposits, dt = 1e-4 s, NLGS tolerance 1e-4")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=120)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("build", help="build directory holding apps/rubble")
    ap.add_argument("--work", default="/tmp/rubble-scaling-bench")
    ap.add_argument("--plot-only", action="store_true", help="re-plot from WORK/scaling.csv")
    ap.add_argument("--quick", action="store_true", help="only N <= 3000 (a check of the script)")
    ap.add_argument("--only", default="", help="comma-separated SHAPE-N cases to (re)run, e.g. polyhedron-30000")
    args = ap.parse_args()
    rubble = os.path.join(os.path.abspath(args.build), "apps", "rubble")
    os.makedirs(args.work, exist_ok=True)
    csv_path = os.path.join(args.work, "scaling.csv")
    fields = ["shape", "n", "steps", "cpu_ms", "wall_ms", "contacts", "sweeps", "residual_max", "settle_cpu_s",
              "startup_cpu_s", "peak_rss_kb", "listed_rss_kb", "load", "top_stages"]
    rows = []
    if os.path.exists(csv_path):
        with open(csv_path) as f:
            for r in csv.DictReader(f):
                for k in ("n", "steps", "peak_rss_kb", "listed_rss_kb"):
                    r[k] = int(r[k])
                for k in ("cpu_ms", "wall_ms", "contacts", "sweeps", "residual_max", "settle_cpu_s", "startup_cpu_s"):
                    r[k] = float(r[k])
                rows.append(r)
    failed = []
    if not args.plot_only:
        only = set(filter(None, args.only.split(",")))
        plan = [p for p in PLAN if (not args.quick or p[1] <= 3000) and (not only or f"{p[0]}-{p[1]}" in only)]
        base = baseline_rss(rubble, args.work)
        print(f"baseline (1-grain run) peak RSS: {base} kB", flush=True)
        for shape, n, steps in plan:
            t0 = time.time()
            try:
                row = run_case(rubble, args.work, shape, n, steps)
            except RuntimeError as error:
                # One case failing (e.g. a settled scene refused) must not lose the others.
                print(f"{shape:10s} N={n:6d}: failed: {error}", flush=True)
                failed.append(f"{shape}-{n}")
                continue
            row["baseline_rss_kb"] = base
            rows = [r for r in rows if not (r["shape"] == shape and r["n"] == n)] + [row]
            print(f"{shape:10s} N={n:6d}: {row['cpu_ms']:8.2f} CPU ms/step ({row['cpu_ms'] * 1e3 / n:.1f} µs/grain), "
                  f"{row['contacts']:.0f} contacts, {row['sweeps']:.1f} sweeps, settle {row['settle_cpu_s']:.0f} s CPU, "
                  f"peak RSS {row['peak_rss_kb']} kB (listed scene {row['listed_rss_kb']} kB), load {row['load']} [{time.time() - t0:.0f} s]", flush=True)
            with open(csv_path, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=fields + ["baseline_rss_kb"], extrasaction="ignore")
                w.writeheader()
                for r in sorted(rows, key=lambda r: (r["shape"], r["n"])):
                    w.writerow(r)
    rows.sort(key=lambda r: (r["shape"] != "sphere", r["n"]))
    print("\n| grains | N | timed steps | CPU ms/step (1 thread) | µs per grain and step | contacts/step | "
          "contacts per grain | NLGS sweeps/step | max residual | largest stages (wall share) | peak RSS MB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {PLURAL[r['shape']]} | {r['n']} | {r['steps']} | {r['cpu_ms']:.2f} | {1e3 * r['cpu_ms'] / r['n']:.1f} | "
              f"{r['contacts']:.0f} | {r['contacts'] / r['n']:.2f} | {r['sweeps']:.1f} | {r['residual_max']:.1e} | "
              f"{r['top_stages']} | {r['peak_rss_kb'] / 1024:.0f} |")
    for shape in ("sphere", "polyhedron"):
        pts = [r for r in rows if r["shape"] == shape]
        if not pts:
            continue
        slope = fit(rows, shape)[0] if len(pts) >= 2 else float("nan")  # one point: no exponent
        big = max(pts, key=lambda r: r["n"])
        base = int(big.get("baseline_rss_kb", 0) or 0)
        per = (big["peak_rss_kb"] - base) * 1024 / big["n"] if base else float("nan")
        print(f"{PLURAL[shape]}: fitted exponent {slope:.2f} (N = {pts[0]['n']} ... {big['n']}); peak RSS at N = {big['n']}: "
              f"{big['peak_rss_kb']} kB, baseline {base} kB -> {per / 1e3:.2f} kB per grain")
    plot(rows, os.path.join(ROOT, "docs", "scaling.png"))
    print(f"plot: {os.path.join(ROOT, 'docs', 'scaling.png')}; table: {csv_path}")
    if failed:
        print(f"failed: {', '.join(failed)} (not measured: not in the table, the fits or the plot)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
