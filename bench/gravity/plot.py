#!/usr/bin/python3
"""Error vs time of the rubble gravity tree: one curve per multipole order, one panel per N.

usage: plot.py results_uniform.csv docs/gravity-error-vs-time.png
The CSV comes from bench_gravity --csv (bench/gravity/run.sh). One thread, tree build included,
CPU seconds (the machine is shared: CPU time is the stable measure of the work);
the error is the per-particle |a_tree - a_direct| / |a_direct| (median solid, p99 dashed).
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# Reference: a Python/numba tree code, uniform sphere, N = 1e5, one thread, build included.
# Measured on 2026-11-22 and not since (it is not a Debian package): not from the same sitting as
# the rubble curves, so the gap is indicative only (bench/RESULTS.md, "Gravity").
REFERENCE = [  # (label, seconds, median, p99)
    ("numba ref. (Nov 22) θ=0.7 monopole", 0.78, 7e-3, 3e-2),
    ("numba ref. (Nov 22) θ=0.5 quadrupole", 2.3, 2.3e-4, 1.2e-3),
]


def error_vs_time(ax, rows, time_column):
    """On ax, the median (solid) and p99 (dashed) force error of the rows against their time_column,
    one curve per multipole order, each point labelled with its θ."""
    for order, color, name in ((1, "tab:blue", "monopole"), (2, "tab:red", "quadrupole")):
        pts = sorted(
            (float(r[time_column]), float(r["median"]), float(r["p99"]), float(r["theta"]))
            for r in rows
            if int(float(r["order"])) == order
        )
        if not pts:
            continue
        t, med, p99, th = zip(*pts)
        ax.loglog(t, med, "o-", color=color, label=f"tree {name}, median")
        ax.loglog(t, p99, "s--", color=color, alpha=0.6, label=f"tree {name}, p99")
        for ti, mi, thi in zip(t, med, th):
            ax.annotate(f"θ={thi:g}", (ti, mi), textcoords="offset points", xytext=(4, -10), fontsize=7)


def main(csv_path, png_path):
    rows = [r for r in csv.DictReader(open(csv_path))
            if r["threads"] in ("1", "1.0") and r.get("precision", "double") == "double"]
    sizes = sorted({int(r["n"]) for r in rows if int(r["n"]) >= 10000})
    fig, axes = plt.subplots(1, len(sizes), figsize=(5 * len(sizes), 4.2), squeeze=False)
    for ax, n in zip(axes[0], sizes):
        error_vs_time(ax, [r for r in rows if int(r["n"]) == n], "cpu_seconds")
        if n == 100000:
            for (label, t, med, p99), m in zip(REFERENCE, ("^", "v")):
                ax.loglog([t], [med], m, color="k", label=label + " (median)")
                ax.loglog([t], [p99], m, color="gray", label=label + " (p99)")
        ax.set_title(f"uniform sphere, N = {n:.0e}, 1 thread")
        ax.set_xlabel("CPU seconds per evaluation (build + walk, 1 thread)")
        ax.set_ylabel("relative acceleration error")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(png_path, dpi=130)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
