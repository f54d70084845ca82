#!/usr/bin/python3
"""The GPU tree against the CPU tree on the same machine: time and error.

usage: plot_gpu.py results_gpu_h200.csv docs/gravity-gpu.png
The CSV comes from bench/gravity/gpu.sh (bench_gravity --backend cpu,cuda --csv on the lent GPU
machine: one NVIDIA H200 and a 16-core host). Left: seconds per evaluation against N at θ = 0.5
quadrupole, the CPU tree on 16 threads and the GPU tree (build, walk, copies and input checks
included), wall clock. Right: the GPU tree's median and p99 force error against its time at
N = 10^6 for θ = 0.3-1.0, monopole and quadrupole.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from plot import error_vs_time  # noqa: E402  (bench/gravity/plot.py, beside this file)


def main(csv_path, png_path):
    # gpu.sh measures N = 10^6, θ = 0.5 quadrupole twice (the N sweep and the θ sweep): keep the first.
    first = {}
    for r in csv.DictReader(open(csv_path)):
        first.setdefault((r["dist"], r["n"], r["theta"], r["order"], r["backend"]), r)
    rows = list(first.values())
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.3))
    styles = {("cpu", "uniform"): ("o-", "tab:blue"), ("cpu", "plummer"): ("s--", "tab:blue"),
              ("cuda", "uniform"): ("o-", "tab:red"), ("cuda", "plummer"): ("s--", "tab:red")}
    for (backend, dist), (style, color) in styles.items():
        pts = sorted((int(r["n"]), float(r["seconds"])) for r in rows
                     if r["backend"] == backend and r["dist"] == dist and float(r["theta"]) == 0.5
                     and int(float(r["order"])) == 2)
        if not pts:
            continue
        n, t = zip(*pts)
        name = "CPU tree, 16 threads" if backend == "cpu" else "GPU tree (H200)"
        left.loglog(n, t, style, color=color, label=f"{name}, {dist}")
    left.axhline(0.3, color="gray", lw=0.8, ls=":")
    left.annotate("0.3 s", (1.2e5, 0.32), fontsize=7, color="gray")
    left.set_xlabel("N particles")
    left.set_ylabel("seconds per evaluation (wall, build and copies included)")
    left.set_title("θ = 0.5 quadrupole: the same tree and errors on both")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=7)
    error_vs_time(right, [r for r in rows if r["backend"] == "cuda" and r["dist"] == "uniform"
                          and int(r["n"]) == 1000000], "seconds")
    right.set_xlabel("seconds per evaluation on the GPU (wall)")
    right.set_ylabel("relative acceleration error")
    right.set_title("GPU tree, uniform sphere, N = 10⁶")
    right.grid(True, which="both", alpha=0.3)
    right.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(png_path, dpi=130)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
