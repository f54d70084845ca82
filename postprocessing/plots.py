#!/usr/bin/env python3
"""Plots of `rubble post` (called by the C++ command with a Python that has matplotlib; see
docs/postprocessing.md, "Plots").

    plots.py run DIR [--scene aggregate|deposit]
                        reads DIR/series.csv, DIR/metrics.csv, DIR/impulse_distribution.csv and
                        writes kinetic_energy.png, conservation.png (when the series has the
                        conservation monitor), coordination.png, impulse_distribution.png, and for
                        an aggregate (the default) also packing_fraction.png, aggregate_diameter.png
    plots.py study DIR  reads DIR/study.csv and writes the comparison plots of the accretion study
                        (figs 3-4 of the LMGC90 accretion paper): study_coordination_vs_ns.png,
                        study_diameter_vs_ns.png (log-log), study_packing_vs_ns.png,
                        study_coordination_vs_mu.png, study_diameter_vs_mu.png,
                        study_packing_vs_mu.png, study_peak_energy_vs_ns.png; runs sharing shape,
                        n_s and mu (seeds) are drawn as their mean with the standard deviation

Columns are described in docs/postprocessing.md. Exits non-zero with a message on bad input.
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)

MINUTE = 60.0


def read_csv(path):
    """Columns of a CSV file as lists: numbers where they parse, text otherwise."""
    if not os.path.exists(path):
        sys.exit(f"plots.py: {path}: no such file")
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    columns = {}
    for row in rows:
        for key, value in row.items():
            try:
                columns.setdefault(key, []).append(float(value))
            except ValueError:
                columns.setdefault(key, []).append(value)
    return columns, len(rows)


def save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def time_axis(times):
    """Minutes when the run is longer than 10 minutes (the paper's unit), seconds otherwise."""
    if times and max(times) > 10 * MINUTE:
        return [t / MINUTE for t in times], "t (min)"
    return list(times), "t (s)"


def conservation_plot(series, path):
    """The run's conservation monitor: energies (J) and the drift of the momenta relative to their
    largest magnitude during the run (a contact-free system under self-gravity keeps all three)."""
    t, label = time_axis(series.get("time", []))
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    for key, name in (("kinetic_energy", "kinetic"), ("potential_energy", "potential"), ("total_energy", "total")):
        top.plot(t, series.get(key, []), lw=1, label=name)
    top.set_ylabel("energy (J)")
    top.set_title("Conservation monitor")
    top.legend()
    for prefix, name in (("linear_momentum", "linear momentum"), ("angular_momentum", "angular momentum (about the centre of mass)")):
        columns = [series.get(f"{prefix}_{c}", []) for c in "xyz"]
        if not all(columns):
            continue
        norms = [math.sqrt(x * x + y * y + z * z) for x, y, z in zip(*columns)]
        scale = max(norms) if norms and max(norms) > 0 else 1.0
        drift = [math.sqrt((x - columns[0][0]) ** 2 + (y - columns[1][0]) ** 2 + (z - columns[2][0]) ** 2) / scale
                 for x, y, z in zip(*columns)]
        bottom.plot(t, drift, lw=1, label=name)
    bottom.set_xlabel(label)
    bottom.set_ylabel("|change| / largest |value|")
    bottom.legend(fontsize=8)
    save(fig, path)


def run_plots(directory, scene="aggregate"):
    """The figures of one run; `scene` "deposit" leaves out those that only make sense for a
    self-gravitating aggregate (its diameter D_max, the packing fraction within it, the inner
    sphere)."""
    aggregate = scene == "aggregate"
    series, _ = read_csv(os.path.join(directory, "series.csv"))
    metrics, snapshots = read_csv(os.path.join(directory, "metrics.csv"))
    impulses, bins = read_csv(os.path.join(directory, "impulse_distribution.csv"))

    fig, ax = plt.subplots(figsize=(6, 4))
    t, label = time_axis(series.get("time", []))
    energy = series.get("mean_kinetic_energy", [])
    if t and any(e > 0 for e in energy):
        ax.semilogy(t, [max(e, 1e-300) for e in energy], lw=1)
    else:
        ax.plot(t, energy, lw=1)
    ax.set_xlabel(label.replace("t (", "simulated time ("))
    ax.set_ylabel(r"mean kinetic energy per grain $\langle E_c \rangle$ (J)")
    ax.set_title("Mean kinetic energy per grain (every step)")
    ax.grid(True, which="major", alpha=0.3)
    save(fig, os.path.join(directory, "kinetic_energy.png"))

    if series.get("total_energy"):
        conservation_plot(series, os.path.join(directory, "conservation.png"))

    t, label = time_axis(metrics.get("time", []))
    label = label.replace("t (", "simulated time (")
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(t, metrics.get("coordination", []), "o-", ms=3, label="all grains")
    ax.plot(t, metrics.get("coordination_without_rattlers", []), "s-", ms=3, label="without rattlers (< 2 contacts)")
    if aggregate:
        ax.plot(t, metrics.get("inner_coordination", []), "^-", ms=3, label="grains of the inner sphere")
    ax.set_xlabel(label)
    ax.set_ylabel("coordination number Z (contacts per grain)")
    ax.set_title(f"Coordination number ({snapshots} snapshots)")
    ax.legend()
    save(fig, os.path.join(directory, "coordination.png"))

    if aggregate:
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.plot(t, metrics.get("packing_fraction", []), "o-", ms=3, label="in the sphere of diameter D_max")
        ax.plot(t, metrics.get("inner_packing_fraction", []), "s-", ms=3, label="in the inner sphere (diameter D_max / 2)")
        ax.set_xlabel(label)
        ax.set_ylabel(r"packing fraction $\nu$ (solid volume / volume)")
        ax.set_title("Packing fraction of the aggregate")
        ax.legend()
        save(fig, os.path.join(directory, "packing_fraction.png"))

        fig, ax = plt.subplots(figsize=(6, 4))
        ax.plot(t, metrics.get("aggregate_diameter", []), "o-", ms=3)
        ax.set_xlabel(label)
        ax.set_ylabel(r"aggregate diameter $D_{max}$ (m)")
        ax.set_title("Aggregate diameter (largest distance between two grains' far sides)")
        save(fig, os.path.join(directory, "aggregate_diameter.png"))

    # Semi-log: the tail of a granular force distribution is exponential, a straight line here.
    fig, ax = plt.subplots(figsize=(6, 4))
    if bins and any(d > 0 for d in impulses["density"]):
        lower, upper = impulses["bin_lower"], impulses["bin_upper"]
        centres = [(lo + up) / 2 for lo, up in zip(lower, upper)]
        ax.bar(lower, impulses["density"], width=[u - l for l, u in zip(lower, upper)], align="edge",
               edgecolor="black", lw=0.5, alpha=0.6, label="histogram")
        ax.semilogy([c for c, d in zip(centres, impulses["density"]) if d > 0],
                    [d for d in impulses["density"] if d > 0], "o", ms=3, color="black", label="bin centres")
        ax.legend()
    else:
        ax.text(0.5, 0.5, "no force-bearing contact", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel(r"normal force / mean normal force, $f_n / \langle f_n \rangle$ (= $r_n / \langle r_n \rangle$)")
    ax.set_ylabel("probability density (log scale)")
    ax.set_title("Normal contact force distribution (last snapshot)")
    save(fig, os.path.join(directory, "impulse_distribution.png"))


def included_rows(study):
    """Rows to plot: those study.csv marks included (all rows in a study.csv without the column)."""
    count = len(study.get("run", []))
    return [i for i in range(count) if study.get("included", [1] * count)[i] == 1]


def grouped(study, rows, key, group_keys):
    """Rows grouped by the values of group_keys; in each group, rows sharing `key` (the seeds of one
    parameter set) are one point: [(x, [rows])] sorted by x."""
    groups = {}
    for i in rows:
        label = tuple(study[g][i] for g in group_keys)
        groups.setdefault(label, {}).setdefault(study[key][i], []).append(i)
    return sorted(((label, sorted(points.items())) for label, points in groups.items()), key=lambda item: str(item[0]))


NAMES = {"shape": "", "friction": "friction μ", "grains": "n_s"}


def study_plot(study, path, x_key, y_keys, group_keys, xlabel, ylabel, title, loglog=False):
    """One curve per group: the mean over the runs of each parameter set, with the standard deviation
    over them as error bars when there are several (seeds); runs that did not end at rest (included
    with --include-unfinished) are drawn as open markers."""
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    markers = {"spheres": "o", "polyhedra": "s", "mixed": "^"}
    status = study.get("status", ["at_rest"] * len(study.get("run", [])))
    rows = included_rows(study)
    seeds = max((len(members) for _, points in grouped(study, rows, x_key, group_keys) for _, members in points), default=1)
    for label, points in grouped(study, rows, x_key, group_keys):
        x = [px for px, _ in points]
        name = ", ".join(f"{NAMES.get(g, g)} = {v:g}" if isinstance(v, float) else str(v) for g, v in zip(group_keys, label))
        for y_key, style in zip(y_keys, ["-", "--"]):
            means, spreads = [], []
            for _, members in points:
                values = [study[y_key][i] for i in members]
                mean = sum(values) / len(values)
                means.append(mean)
                spreads.append(math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1)) if len(values) > 1 else 0.0)
            curve = name + (f" ({y_key.replace('_', ' ')})" if len(y_keys) > 1 else "")
            line = ax.errorbar(x, means, yerr=spreads if seeds > 1 else None, fmt=style, marker=markers.get(label[0], "o"),
                               capsize=3, label=curve)
            unfinished = [(px, m) for (px, members), m in zip(points, means) if any(status[i] != "at_rest" for i in members)]
            if unfinished:
                ax.plot([p for p, _ in unfinished], [m for _, m in unfinished], linestyle="none", marker="o", ms=11,
                        markerfacecolor="none", color=line[0].get_color(),
                        label="not at rest (--include-unfinished)" if y_key == y_keys[0] else None)
    if loglog:
        ax.set_xscale("log")
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title + (f"\nmean ± standard deviation over up to {seeds} runs (seeds)" if seeds > 1 else ""),
                 fontsize=10)
    ax.legend(fontsize=7)
    save(fig, path)


def study_plots(directory):
    study, runs = read_csv(os.path.join(directory, "study.csv"))
    if runs == 0 or not included_rows(study):
        sys.exit(f"plots.py: {directory}/study.csv has no run to plot")
    out = lambda name: os.path.join(directory, name)  # noqa: E731
    by_mu = ["shape", "friction"]
    by_ns = ["shape", "grains"]
    ns = r"number of grains $n_s$"
    mu = r"friction coefficient $\mu$"
    z = r"coordination number $Z_{max}$ (contacts per grain)"
    nu = r"packing fraction $\nu$ of the aggregate"
    study_plot(study, out("study_coordination_vs_ns.png"), "grains", ["Z_max"], by_mu, ns, z,
               "Coordination number at rest against the number of grains")
    study_plot(study, out("study_diameter_vs_ns.png"), "grains", ["D_max_over_mean_d", "D_max_over_d_star"], by_mu, ns,
               r"aggregate size $D_{max}/\langle d\rangle$ (solid), $D_{max}/d^*$ (dashed)",
               "Aggregate diameter in grain diameters against the number of grains", loglog=True)
    study_plot(study, out("study_packing_vs_ns.png"), "grains", ["packing_fraction"], by_mu, ns, nu,
               "Packing fraction at rest against the number of grains")
    study_plot(study, out("study_coordination_vs_mu.png"), "friction", ["Z_max"], by_ns, mu, z,
               "Coordination number at rest against friction")
    study_plot(study, out("study_diameter_vs_mu.png"), "friction", ["D_max_over_mean_d"], by_ns, mu,
               r"aggregate size $D_{max}/\langle d\rangle$", "Aggregate diameter in grain diameters against friction")
    study_plot(study, out("study_packing_vs_mu.png"), "friction", ["packing_fraction"], by_ns, mu, nu,
               "Packing fraction at rest against friction")
    study_plot(study, out("study_peak_energy_vs_ns.png"), "grains", ["peak_mean_kinetic_energy"], by_mu, ns,
               r"peak mean kinetic energy per grain $\langle E_c\rangle$ (J)",
               "Peak kinetic energy of the collapse against the number of grains")


def main(argv):
    usage = "usage: plots.py run DIR [--scene aggregate|deposit] | plots.py study DIR"
    if len(argv) < 3 or argv[1] not in ("run", "study"):
        sys.exit(usage)
    if argv[1] == "run":
        scene = "aggregate"
        if len(argv) == 5 and argv[3] == "--scene" and argv[4] in ("aggregate", "deposit"):
            scene = argv[4]
        elif len(argv) != 3:
            sys.exit(usage)
        run_plots(argv[2], scene)
    elif len(argv) == 3:
        study_plots(argv[2])
    else:
        sys.exit(usage)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
