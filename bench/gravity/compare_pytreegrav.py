#!/usr/bin/env python3
"""rubble's tree gravity against pytreegrav's on the same particles, at equal error, one thread.

For each distribution and N, `bench_gravity` (this folder) times rubble's tree over a grid of
opening angles, both expansion orders and both kernel precisions, and writes the particles, the
error targets and their exact direct-sum accelerations (--write-reference). This script then
times pytreegrav (Grudić & Gurvich 2021; a Python/numba Barnes-Hut code, `Accel(..., method="tree",
parallel=False)`) on that file, judges its accelerations on the same targets with the same
measure (per-particle |a - a_exact| / |a_exact|, median and 99th percentile), and pairs each
pytreegrav row with the cheapest rubble row that is as accurate, in three ways: median error no
larger (any kernel precision); median and 99th percentile no larger (any precision); both no
larger with the default double-precision kernels. The whole sequence runs --rounds times,
alternating the two codes, and each figure is the best over rounds and --reps: interleaved runs
of one sitting. Every timed row goes to OUT's "-raw" sibling as well.

CPU time: `time.process_time()` around each pytreegrav call (user + system of the process, as
bench_gravity's CLOCK_PROCESS_CPUTIME_ID); numba's compilation is excluded by a warm-up call on
2 000 particles for each order first. NUMBA_NUM_THREADS=1 and OMP_NUM_THREADS=1 are set.

Needs numpy and numba (Debian: python3-numpy python3-numba) and a pytreegrav source tree
(--pytreegrav DIR, the folder holding the `pytreegrav` package, e.g. a checkout's src/), which is
not a Debian package. Usage (from the repository root, after building bench_gravity):

  bench/gravity/compare_pytreegrav.py --bench build/ci/bench/gravity/bench_gravity \\
      --pytreegrav PYTREEGRAV/src --n 100000,1000000 --out compare.csv
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ["OMP_NUM_THREADS"] = "1"

import numpy as np  # noqa: E402


def read_reference(path):
    """The file bench_gravity --write-reference writes: positions, masses, targets, exact accelerations."""
    with open(path, "rb") as f:
        if f.read(8) != b"RUBGRAV1":
            sys.exit(f"{path}: not a bench_gravity reference file (no RUBGRAV1 header)")
        n, k = np.frombuffer(f.read(16), dtype="<u8")
        pos = np.frombuffer(f.read(24 * int(n)), dtype="<f8").reshape(-1, 3)
        mass = np.frombuffer(f.read(8 * int(n)), dtype="<f8")
        targets = np.frombuffer(f.read(8 * int(k)), dtype="<u8").astype(np.int64)
        exact = np.frombuffer(f.read(24 * int(k)), dtype="<f8").reshape(-1, 3)
    if len(exact) != k:
        sys.exit(f"{path}: truncated")
    return pos.copy(), mass.copy(), targets, exact


def errors(acc, targets, exact):
    e = np.linalg.norm(acc[targets] - exact, axis=1) / np.linalg.norm(exact, axis=1)
    # bench_gravity's percentile: the element at floor(p (K - 1)) of the sorted errors
    s = np.sort(e)
    return s[int(0.5 * (len(s) - 1))], s[int(0.99 * (len(s) - 1))]


def run_rubble(bench, dist, n, thetas, reps, folder):
    out = os.path.join(folder, f"rubble-{dist}-{n}.csv")
    cmd = [bench, "--dist", dist, "--n", str(n), "--theta", thetas, "--order", "1,2", "--threads", "1",
           "--reps", str(reps), "--precision", "double,single", "--csv", out, "--write-reference", folder]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=dict(os.environ, OMP_NUM_THREADS="1"))
    with open(out) as f:
        return [{"theta": float(r["theta"]), "order": int(r["order"]), "precision": r["precision"],
                 "cpu": float(r["cpu_seconds"]), "median": float(r["median"]), "p99": float(r["p99"])}
                for r in csv.DictReader(f)]


def run_pytreegrav(ptg, pos, mass, targets, exact, thetas, reps):
    rows = []
    for order in (1, 2):
        for theta in thetas:
            best = float("inf")
            for _ in range(reps):
                t0 = time.process_time()
                acc = ptg.Accel(pos, mass, np.zeros(len(mass)), theta=theta, method="tree", parallel=False,
                                quadrupole=order == 2)
                best = min(best, time.process_time() - t0)
            median, p99 = errors(acc, targets, exact)
            rows.append({"theta": theta, "order": order, "cpu": best, "median": median, "p99": p99})
    return rows


def best_of(rounds, key):
    """Per configuration (key), the row of least CPU over the rounds."""
    best = {}
    for rows in rounds:
        for r in rows:
            k = key(r)
            if k not in best or r["cpu"] < best[k]["cpu"]:
                best[k] = r
    return list(best.values())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bench", required=True, help="bench_gravity executable")
    ap.add_argument("--pytreegrav", default="", help="folder holding the pytreegrav package (else: installed)")
    ap.add_argument("--n", default="100000,1000000")
    ap.add_argument("--dist", default="uniform,plummer")
    ap.add_argument("--theta", default="0.3,0.4,0.5,0.6,0.7,0.8,1.0", help="rubble's opening angles")
    ap.add_argument("--reference-theta", default="0.5,0.7", help="pytreegrav's opening angles")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", default="compare_pytreegrav.csv")
    args = ap.parse_args()
    if args.pytreegrav:
        sys.path.insert(0, args.pytreegrav)
    import pytreegrav as ptg

    rng = np.random.default_rng(1)
    warm = rng.random((2000, 3))
    for quad in (False, True):  # numba compiles on the first call: not timed
        ptg.Accel(warm, np.ones(2000), np.zeros(2000), theta=0.7, method="tree", parallel=False, quadrupole=quad)

    ref_thetas = [float(t) for t in args.reference_theta.split(",")]
    table, raw = [], []
    with tempfile.TemporaryDirectory() as folder:
        for dist in args.dist.split(","):
            for n in (int(float(x)) for x in args.n.split(",")):
                rubble_rounds, ptg_rounds = [], []
                for _ in range(args.rounds):
                    rubble_rounds.append(run_rubble(args.bench, dist, n, args.theta, args.reps, folder))
                    pos, mass, targets, exact = read_reference(os.path.join(folder, f"{dist}-{n}.bin"))
                    ptg_rounds.append(run_pytreegrav(ptg, pos, mass, targets, exact, ref_thetas, args.reps))
                rubble = best_of(rubble_rounds, lambda r: (r["theta"], r["order"], r["precision"]))
                reference = best_of(ptg_rounds, lambda r: (r["theta"], r["order"]))
                raw += [dict(r, code="rubble", dist=dist, n=n) for r in rubble]
                raw += [dict(r, code="pytreegrav", precision="double", dist=dist, n=n) for r in reference]
                for p in sorted(reference, key=lambda r: (r["order"], r["theta"])):
                    row = {"dist": dist, "n": n, "order": p["order"], "theta": p["theta"],
                           "pytreegrav_cpu": p["cpu"], "pytreegrav_median": p["median"], "pytreegrav_p99": p["p99"]}
                    line = (f"{dist} N={n} order {p['order']} theta {p['theta']:g}: pytreegrav {p['cpu']:.4g} s "
                            f"(median {p['median']:.2e}, p99 {p['p99']:.2e})")
                    for name, accurate in PAIRINGS:
                        equal = [r for r in rubble if accurate(r, p)]
                        if not equal:
                            line += f"; {name}: no rubble row as accurate"
                            continue
                        c = min(equal, key=lambda r: r["cpu"])
                        row.update({f"{name}_rubble": f"theta {c['theta']:g} order {c['order']} {c['precision']}",
                                    f"{name}_cpu": c["cpu"], f"{name}_median": c["median"], f"{name}_p99": c["p99"],
                                    f"{name}_ratio": p["cpu"] / c["cpu"]})
                        line += (f"; {name}: theta {c['theta']:g} order {c['order']} {c['precision']} {c['cpu']:.4g} s "
                                 f"({c['median']:.2e}, {c['p99']:.2e}) {p['cpu'] / c['cpu']:.1f}x")
                    table.append(row)
                    print(line, flush=True)
    write_csv(args.out, table)
    write_csv(os.path.splitext(args.out)[0] + "-raw.csv", raw)


# The three senses of "as accurate" (see the docstring): name, test of a rubble row r against a pytreegrav row p.
PAIRINGS = [
    ("median", lambda r, p: r["median"] <= p["median"]),
    ("median_p99", lambda r, p: r["median"] <= p["median"] and r["p99"] <= p["p99"]),
    ("double_median_p99", lambda r, p: r["precision"] == "double" and r["median"] <= p["median"]
     and r["p99"] <= p["p99"]),
]


def write_csv(path, rows):
    fields = list(dict.fromkeys(k for row in rows for k in row))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
