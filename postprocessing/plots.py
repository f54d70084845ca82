#!/usr/bin/python3
"""Plots of `rubble post` (called by the C++ command; run with /usr/bin/python3, matplotlib).

    plots.py run DIR    reads DIR/series.csv, DIR/metrics.csv, DIR/impulse_distribution.csv and
                        writes kinetic_energy.png, conservation.png (when the series has the
                        conservation monitor), coordination.png, packing_fraction.png,
                        aggregate_diameter.png, impulse_distribution.png
    plots.py study DIR  reads DIR/study.csv and writes the comparison plots of seed 001 figs 3-4:
                        study_coordination_vs_ns.png, study_diameter_vs_ns.png (log-log),
                        study_packing_vs_ns.png, study_coordination_vs_mu.png,
                        study_diameter_vs_mu.png, study_packing_vs_mu.png,
                        study_peak_energy_vs_ns.png

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


def run_plots(directory):
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
    ax.set_xlabel(label)
    ax.set_ylabel(r"$\langle E_c \rangle$ (J per grain)")
    ax.set_title("Mean kinetic energy")
    save(fig, os.path.join(directory, "kinetic_energy.png"))

    if series.get("total_energy"):
        conservation_plot(series, os.path.join(directory, "conservation.png"))

    t, label = time_axis(metrics.get("time", []))
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(t, metrics.get("coordination", []), "o-", ms=3, label="Z (all grains)")
    ax.plot(t, metrics.get("coordination_without_rattlers", []), "s-", ms=3, label="Z without rattlers")
    ax.plot(t, metrics.get("inner_coordination", []), "^-", ms=3, label="Z of the inner sphere")
    ax.set_xlabel(label)
    ax.set_ylabel("Z")
    ax.set_title(f"Coordination number ({snapshots} snapshots)")
    ax.legend()
    save(fig, os.path.join(directory, "coordination.png"))

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(t, metrics.get("packing_fraction", []), "o-", ms=3, label=r"$\nu$ (sphere of diameter $D_{max}$)")
    ax.plot(t, metrics.get("inner_packing_fraction", []), "s-", ms=3, label=r"inner sphere ($D_{max}/2$)")
    ax.set_xlabel(label)
    ax.set_ylabel(r"$\nu$")
    ax.set_title("Packing fraction")
    ax.legend()
    save(fig, os.path.join(directory, "packing_fraction.png"))

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(t, metrics.get("aggregate_diameter", []), "o-", ms=3)
    ax.set_xlabel(label)
    ax.set_ylabel(r"$D_{max}$ (m)")
    ax.set_title("Aggregate diameter")
    save(fig, os.path.join(directory, "aggregate_diameter.png"))

    fig, ax = plt.subplots(figsize=(6, 4))
    if bins:
        lower, upper = impulses["bin_lower"], impulses["bin_upper"]
        ax.bar(lower, impulses["density"], width=[u - l for l, u in zip(lower, upper)], align="edge",
               edgecolor="black", lw=0.5)
    else:
        ax.text(0.5, 0.5, "no force-bearing contact", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel(r"$r_n / \langle r_n \rangle$")
    ax.set_ylabel("probability density")
    ax.set_title("Normal impulse distribution (last snapshot)")
    save(fig, os.path.join(directory, "impulse_distribution.png"))


def grouped(study, key, group_keys):
    """Rows of the study grouped by the values of group_keys, each group sorted by `key`."""
    groups = {}
    for i in range(len(study[key])):
        label = tuple(study[g][i] for g in group_keys)
        groups.setdefault(label, []).append(i)
    for label in groups:
        groups[label].sort(key=lambda i: study[key][i])
    return sorted(groups.items(), key=lambda item: str(item[0]))


def study_plot(study, path, x_key, y_keys, group_keys, xlabel, ylabel, loglog=False):
    fig, ax = plt.subplots(figsize=(6, 4))
    markers = {"spheres": "o", "polyhedra": "s", "mixed": "^"}
    for label, rows in grouped(study, x_key, group_keys):
        x = [study[x_key][i] for i in rows]
        for y_key, style in zip(y_keys, ["-", "--"]):
            y = [study[y_key][i] for i in rows]
            name = ", ".join(f"{g} = {v:g}" if isinstance(v, float) else str(v) for g, v in zip(group_keys, label))
            if len(y_keys) > 1:
                name += f" ({y_key})"
            ax.plot(x, y, style, marker=markers.get(label[0], "o"), label=name)
    if loglog:
        ax.set_xscale("log")
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)
    save(fig, path)


def study_plots(directory):
    study, runs = read_csv(os.path.join(directory, "study.csv"))
    if runs == 0:
        sys.exit(f"plots.py: {directory}/study.csv has no run")
    out = lambda name: os.path.join(directory, name)  # noqa: E731
    by_mu = ["shape", "friction"]
    by_ns = ["shape", "grains"]
    study_plot(study, out("study_coordination_vs_ns.png"), "grains", ["Z_max"], by_mu, r"$n_s$", r"$Z_{max}$")
    study_plot(study, out("study_diameter_vs_ns.png"), "grains", ["D_max_over_mean_d", "D_max_over_d_star"], by_mu,
               r"$n_s$", r"$D_{max}/\langle d\rangle$ (solid), $D_{max}/d^*$ (dashed)", loglog=True)
    study_plot(study, out("study_packing_vs_ns.png"), "grains", ["packing_fraction"], by_mu, r"$n_s$", r"$\nu$")
    study_plot(study, out("study_coordination_vs_mu.png"), "friction", ["Z_max"], by_ns, r"$\mu$", r"$Z_{max}$")
    study_plot(study, out("study_diameter_vs_mu.png"), "friction", ["D_max_over_mean_d"], by_ns, r"$\mu$",
               r"$D_{max}/\langle d\rangle$")
    study_plot(study, out("study_packing_vs_mu.png"), "friction", ["packing_fraction"], by_ns, r"$\mu$", r"$\nu$")
    study_plot(study, out("study_peak_energy_vs_ns.png"), "grains", ["peak_mean_kinetic_energy"], by_mu, r"$n_s$",
               r"peak $\langle E_c\rangle$ (J)")


def main(argv):
    if len(argv) != 3 or argv[1] not in ("run", "study"):
        sys.exit("usage: plots.py run|study DIR")
    if argv[1] == "run":
        run_plots(argv[2])
    else:
        study_plots(argv[2])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
