#!/usr/bin/env python3
"""Plots of `rubble post` (called by the C++ command with a Python that has matplotlib; see
docs/postprocessing.md, "Plots").

    plots.py run DIR [--scene aggregate|deposit]
                        reads DIR/series.csv, DIR/metrics.csv, DIR/impulse_distribution.csv and
                        writes kinetic_energy.png, conservation.png (when the series has the
                        conservation monitor), coordination.png, impulse_distribution.png, and for
                        an aggregate (the default) also packing_fraction.png, aggregate_diameter.png
    plots.py study DIR  reads DIR/study.csv, DIR/study_fits.csv and DIR/study_kinetic_energy.csv
                        (written by `rubble post --study`) and draws the panels of figs 3-4 of the
                        LMGC90 accretion paper: study_kinetic_energy.png, study_coordination.png,
                        study_diameter.png (log-log, fitted exponents), study_packing.png (each
                        with an inset against mu when the study has a mu sweep) and
                        study_peak_energy.png; each point is a parameter set's mean over the
                        window, with the window's spread (one run) or the spread over its runs
                        (seeds) as error bar

Without matplotlib it warns and exits 0 without drawing.

Columns are described in docs/postprocessing.md. Exits non-zero with a message on bad input.
"""
import csv
import math
import os
import sys
import textwrap

try:
    import matplotlib
except ImportError:  # plots are a convenience: say so and leave every table as it is
    sys.stderr.write("plots.py: warning: matplotlib is not installed here (Debian: apt-get install "
                     "python3-matplotlib); no figure drawn\n")
    sys.exit(0)

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
from matplotlib.ticker import FuncFormatter, NullFormatter, NullLocator  # noqa: E402

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
    ax.plot(t, metrics.get("coordination_without_rattlers", []), "s-", ms=3, label="without rattlers (< 2 contacts, iterated)")
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


def complete(study, i):
    """True when run i ran to its end (at rest or at its end time) and reached the window (the
    others are drawn as open markers)."""
    reached = study.get("reached_window", [1] * len(study["run"]))[i] == 1
    return study["status"][i] in ("at_rest", "end_time") and reached


def number(value):
    """A study.csv cell as a float (NaN for an empty cell: a quantity that does not apply)."""
    return value if isinstance(value, float) else float("nan")


def sweep_groups(study, rows, x_key, group_keys):
    """{group label: {x: [rows]}} for the rows; a group is a series of the plot (a shape and a mu
    against n_s, or a shape and an n_s against mu) and the rows sharing x are the seeds of one
    parameter set."""
    groups = {}
    for i in rows:
        label = tuple(study[g][i] for g in group_keys)
        groups.setdefault(label, {}).setdefault(study[x_key][i], []).append(i)
    return groups


def point(study, members, key):
    """Mean and error bar of one parameter set: with one run, the spread of `key` over its window
    (the column key_spread); with several runs (seeds), the standard deviation of their means."""
    values = [number(study[key][i]) for i in members]
    mean = sum(values) / len(values)
    if len(values) > 1:
        return mean, math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
    spread = study.get(key + "_spread")
    return mean, (number(spread[members[0]]) if spread else 0.0)


def capped_share(study, members):
    """The largest share, over the runs of a parameter set, of window steps that ended at the
    solver's sweep cap (study.csv capped_steps / window_steps; 0 where unknown): such a point's
    values carry the solver's error, and the plot says so beside it."""
    capped, steps = study.get("capped_steps"), study.get("window_steps")
    if capped is None or steps is None:
        return 0.0
    shares = [number(capped[i]) / number(steps[i]) for i in members if number(steps[i]) > 0]
    return max((share for share in shares if share > 0.0), default=0.0)


MARKERS = {"spheres": "o", "polyhedra": "s", "mixed": "^"}


def series_name(label, group_keys):
    parts = []
    for key, value in zip(group_keys, label):
        if key == "shape":
            parts.append(str(value))
        elif key == "friction":
            parts.append(f"μ = {value:g}")
        elif key == "grains":
            parts.append(f"$n_s$ = {value:g}")
    return ", ".join(parts)


def draw_series(ax, study, groups, group_keys, y_key, style="-", filled=True, suffix="", fits=None):
    """One curve per group (mean ± error bar per parameter set), one colour per group whatever the
    quantity (so that a group's second quantity, dashed with open markers, matches its first);
    runs not complete (kept with --include-unfinished) ringed; a fitted power law drawn through
    the points when `fits` has it."""
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for n, (label, points) in enumerate(sorted(groups.items(), key=lambda item: str(item[0]))):
        xs = sorted(points)
        stats = [point(study, points[x], y_key) for x in xs]
        shape = label[0]
        colour = colours[n % len(colours)]
        ax.errorbar(xs, [m for m, _ in stats], yerr=[e for _, e in stats], fmt=style, color=colour,
                    marker=MARKERS.get(shape, "o"), capsize=3, ms=6,
                    markerfacecolor=colour if filled else "white",
                    label=series_name(label, group_keys) + suffix)
        flagged = [(x, m) for x, (m, _) in zip(xs, stats) if not all(complete(study, i) for i in points[x])]
        if flagged:
            ax.plot([x for x, _ in flagged], [m for _, m in flagged], linestyle="none", marker="o", ms=13,
                    markerfacecolor="none", color=colour)
        for x, (m, _) in zip(xs, stats):
            capped = capped_share(study, points[x])
            if capped > 0.0:
                ax.annotate(f"sweep cap: {100.0 * capped:.0f} % of steps", (x, m), xytext=(-6, -3),
                            textcoords="offset points", ha="right", va="top", fontsize=6, color=colour)
        if fits is not None and len(xs) >= 2:
            fit = fits.get((shape, label[1] if len(label) > 1 else 0.0, y_key, "power"))
            if fit:
                a, b = fit
                grid = [xs[0] * (xs[-1] / xs[0]) ** (k / 50) for k in range(51)]
                ax.plot(grid, [a * x ** b for x in grid], ":", color=colour, lw=1,
                        label=f"fit {series_name(label, group_keys)}{suffix} ∝ $n_s^{{{b:.3f}}}$")


def read_fits(directory):
    path = os.path.join(directory, "study_fits.csv")
    fits = {}
    if not os.path.exists(path):
        return fits
    columns, count = read_csv(path)
    for k in range(count):
        key = (columns["shape"][k], columns["friction"][k], columns["quantity"][k], columns["model"][k])
        fits[key] = (columns["prefactor"][k], columns["exponent"][k])
    return fits


def split_series(study, rows):
    """The n_s series (shape, mu groups with two or more n_s; all groups when none has) and the mu
    sweeps (shape, n_s groups with two or more mu) of the rows."""
    by_ns = sweep_groups(study, rows, "grains", ["shape", "friction"])
    by_mu = sweep_groups(study, rows, "friction", ["shape", "grains"])
    # A (shape, mu) group is an n_s series when it has two n_s or more, or when mu is the shape's
    # smallest (a single polyhedron n_s at mu = 0 belongs beside the spheres' series); the other
    # single points are the mu sweep, drawn in the inset.
    lowest = {}
    for shape, friction in by_ns:
        lowest[shape] = min(friction, lowest.get(shape, friction))
    ns_series = {k: v for k, v in by_ns.items() if len(v) >= 2 or k[1] == lowest[k[0]]}
    mu_series = {k: v for k, v in by_mu.items() if len(v) >= 2}
    return ns_series, mu_series


def plain_numbers(ax, minor_y=False, x_ticks=None):
    """Log axes labelled 100, 1000 and 6, 7, 8 rather than 10^2 and 7 x 10^0; with minor_y the
    y axis's minor ticks are labelled too (a ratio spanning less than a decade); x_ticks (the
    study's n_s) replace the decades on x, which a study from 125 to 512 grains would not reach."""
    plain = FuncFormatter(lambda value, _: f"{value:g}")
    if x_ticks:
        ax.set_xticks(sorted(set(x_ticks)))
        ax.xaxis.set_minor_locator(NullLocator())
    ax.xaxis.set_major_formatter(plain)
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_major_formatter(plain)
    ax.yaxis.set_minor_formatter(plain if minor_y else NullFormatter())


def panels(mu_series):
    """The figure, its main axes (against n_s) and, when the study has a mu sweep, a side panel
    against mu (the paper's inset, beside the curves rather than over them)."""
    if not mu_series:
        fig, ax = plt.subplots(figsize=(7, 4.8))
        return fig, ax, None
    fig, (ax, side) = plt.subplots(1, 2, figsize=(10, 4.8), gridspec_kw={"width_ratios": [2.4, 1]})
    return fig, ax, side


def mu_panel(side, study, mu_series, y_key, ylabel):
    """y against mu for the mu sweeps (several mu at one n_s): the paper's insets of figs 3b, 4b."""
    if side is None:
        return
    draw_series(side, study, mu_series, ["shape", "grains"], y_key)
    side.set_xlabel(r"friction coefficient $\mu$")
    side.set_ylabel(ylabel)
    side.set_title("against friction (the paper's inset)", fontsize=8)
    side.legend(fontsize=6)


def caption(study, rows, window):
    seeds = max((len(m) for g in sweep_groups(study, rows, "grains", ["shape", "friction"]).values()
                 for m in g.values()), default=1)
    spread = ("error bars: standard deviation over the runs (seeds) of a parameter set" if seeds > 1
              else "error bars: standard deviation over the window's snapshots")
    return f"mean over the window t ≥ {window / MINUTE:.4g} min; {spread}"


def title(ax, heading, note):
    """A figure title in words, with the averaging note wrapped under it."""
    ax.set_title(heading + "\n" + "\n".join(textwrap.wrap(note, 95)), fontsize=8)


def energy_plot(study, rows, directory, window):
    """Fig. 3a: <E_c>(t) of every run, log y, the paper's 20 min peak and the 125 min window
    marked, each run's rest time (the stop of `until = "rest"`) as a dot on its curve."""
    curves, count = read_csv(os.path.join(directory, "study_kinetic_energy.csv"))
    fig, ax = plt.subplots(figsize=(7, 4.8))
    order = sorted(rows, key=lambda i: (study["shape"][i], study["friction"][i], study["grains"][i]))
    colours = plt.get_cmap("viridis")
    sizes = sorted({study["grains"][i] for i in rows})
    for i in order:
        t = [curves["time"][k] / MINUTE for k in range(count) if int(curves["row"][k]) == i]
        e = [max(curves["mean_kinetic_energy"][k], 1e-300) for k in range(count) if int(curves["row"][k]) == i]
        colour = colours(sizes.index(study["grains"][i]) / max(1, len(sizes) - 1) * 0.9)
        style = "-" if study["shape"][i] == "spheres" else "--"
        label = f"{study['shape'][i]}, $n_s$ = {study['grains'][i]:g}, μ = {study['friction'][i]:g}"
        if not complete(study, i):
            label += " (cut short or short of the window)"
        ax.semilogy(t, e, style, color=colour, lw=1, label=label)
        rest = number(study["rest_time"][i])
        if not math.isnan(rest) and t:
            k = min(range(len(t)), key=lambda j: abs(t[j] - rest / MINUTE))
            ax.plot([t[k]], [e[k]], "o", color=colour, ms=5)
    ax.axvline(20, color="grey", ls=":", lw=1)
    ax.axvline(window / MINUTE, color="black", ls="--", lw=1)
    ax.text(20, 0.98, " paper's peak ≈ 20 min", transform=ax.get_xaxis_transform(), fontsize=7, va="top")
    ax.text(window / MINUTE, 0.98, f" window t ≥ {window / MINUTE:.4g} min", transform=ax.get_xaxis_transform(),
            fontsize=7, va="top")
    ax.plot([], [], "o", color="grey", label="rest time of the run (dot)")
    ax.set_xlabel("simulated time t (min)")
    ax.set_ylabel(r"mean kinetic energy per grain $\langle E_c \rangle$ (J)")
    ax.set_title("Mean kinetic energy per grain during the accretion (paper fig. 3a)", fontsize=10)
    ax.legend(fontsize=6, loc="lower left")  # the curves start there but leave it at once
    save(fig, os.path.join(directory, "study_kinetic_energy.png"))


def study_plots(directory):
    study, runs = read_csv(os.path.join(directory, "study.csv"))
    rows = included_rows(study)
    if runs == 0 or not rows:
        sys.exit(f"plots.py: {directory}/study.csv has no run to plot")
    window = study["window_start"][0]
    fits = read_fits(directory)
    ns = r"number of grains $n_s$"
    ns_series, mu_series = split_series(study, rows)
    note = caption(study, rows, window)
    ringed = "; ringed: runs cut short or short of the window (--include-unfinished)" if not all(
        complete(study, i) for i in rows) else ""

    energy_plot(study, rows, directory, window)

    fig, ax, side = panels(mu_series)
    draw_series(ax, study, ns_series, ["shape", "friction"], "Z_max")
    draw_series(ax, study, ns_series, ["shape", "friction"], "Z_without_rattlers", style="--", filled=False,
                suffix=", without rattlers")
    ax.set_xscale("log")
    plain_numbers(ax, x_ticks=[study["grains"][i] for i in rows])
    ax.set_xlabel(ns)
    ax.set_ylabel(r"coordination number $Z_{max}$ (contacts per grain)")
    title(ax, "Coordination number against the number of grains (paper fig. 3b)", note + ringed)
    ax.legend(fontsize=6, loc="best")
    mu_panel(side, study, mu_series, "Z_max", r"$Z_{max}$")
    save(fig, os.path.join(directory, "study_coordination.png"))

    fig, ax, side = panels(mu_series)
    draw_series(ax, study, ns_series, ["shape", "friction"], "D_max_over_mean_d", fits=fits,
                suffix=r": $D_{max}/\langle d\rangle$")
    draw_series(ax, study, ns_series, ["shape", "friction"], "D_max_over_d_star", style="--", filled=False,
                fits=fits, suffix=r": $D_{max}/d^*$")
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_numbers(ax, minor_y=True, x_ticks=[study["grains"][i] for i in rows])
    ax.set_xlabel(ns)
    ax.set_ylabel(r"aggregate diameter / grain diameter")
    title(ax, "Aggregate diameter against the number of grains, log-log (paper fig. 4a and inset)", note + ringed)
    ax.legend(fontsize=6, loc="best")
    mu_panel(side, study, mu_series, "D_max_over_mean_d", r"$D_{max}/\langle d\rangle$")
    save(fig, os.path.join(directory, "study_diameter.png"))

    fig, ax, side = panels(mu_series)
    draw_series(ax, study, ns_series, ["shape", "friction"], "packing_fraction",
                suffix=r": $\nu$ (sphere of diameter $D_{max}$)")
    draw_series(ax, study, ns_series, ["shape", "friction"], "inertia_packing_fraction", style="--", filled=False,
                suffix=r": $\nu_I$ (inertia ellipsoid)")
    ax.set_xscale("log")
    plain_numbers(ax, x_ticks=[study["grains"][i] for i in rows])
    ax.set_xlabel(ns)
    ax.set_ylabel(r"packing fraction (grain volume / aggregate volume)")
    title(ax, "Packing fraction against the number of grains (paper fig. 4b)", note + ringed)
    ax.legend(fontsize=6, loc="best")
    mu_panel(side, study, mu_series, "packing_fraction", r"$\nu$")
    save(fig, os.path.join(directory, "study_packing.png"))

    # The peak of <E_c>: power law and exponential fitted (the paper says "exponentially").
    fig, ax = plt.subplots(figsize=(7, 4.8))
    groups = sweep_groups(study, rows, "grains", ["shape", "friction"])
    for label, points in sorted(groups.items(), key=lambda item: str(item[0])):
        xs = sorted(points)
        stats = [point(study, points[x], "peak_mean_kinetic_energy") for x in xs]
        line = ax.errorbar(xs, [m for m, _ in stats], yerr=[e for _, e in stats], fmt="-",
                           marker=MARKERS.get(label[0], "o"), capsize=3, label=series_name(label, ["shape", "friction"]))
        colour = line[0].get_color()
        if len(xs) >= 2:
            grid = [xs[0] * (xs[-1] / xs[0]) ** (k / 50) for k in range(51)]
            power = fits.get((label[0], label[1], "peak_mean_kinetic_energy", "power"))
            if power:
                ax.plot(grid, [power[0] * x ** power[1] for x in grid], ":", color=colour,
                        label=f"power law ∝ $n_s^{{{power[1]:.3f}}}$")
            exponential = fits.get((label[0], label[1], "peak_mean_kinetic_energy", "exponential"))
            if exponential:
                ax.plot(grid, [exponential[0] * math.exp(exponential[1] * x) for x in grid], "-.", color=colour,
                        lw=1, label=f"exponential ∝ exp({exponential[1]:.3g} $n_s$)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_numbers(ax, minor_y=True, x_ticks=[study["grains"][i] for i in rows])
    ax.set_xlabel(ns)
    ax.set_ylabel(r"peak of $\langle E_c \rangle$ (J per grain)")
    ax.set_title("Peak mean kinetic energy against the number of grains (paper fig. 3a inset)\n"
                 "error bars: standard deviation over the runs (seeds) of a parameter set", fontsize=8)
    ax.legend(fontsize=6)
    save(fig, os.path.join(directory, "study_peak_energy.png"))


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
