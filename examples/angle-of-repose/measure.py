#!/usr/bin/python3
"""Measure the angle of repose of heaps poured by rubble (examples/angle-of-repose/).

Usage:
  /usr/bin/python3 examples/angle-of-repose/measure.py RUN.h5 [RUN.h5 ...] [--plot FILE.png] [--csv FILE.csv]

For each run file, from its last snapshot:
  * the grains are the bodies of nonzero mass in play (the fixed floor spheres are stored with mass 0);
  * the heap's axis is the vertical line through the grains' horizontal centroid;
  * the surface height h(r) is, in radial bins one mean grain diameter wide, the top (z + radius) of
    the highest grain in the bin, taken separately in each of 8 azimuthal sectors of 45 degrees;
  * the slope's middle part is the range of r where the mean (over sectors) surface height lies between
    25% and 75% of the heap's height above the floor, H = h at the axis (the rounded apex and the curved toe
    are left out);
  * the angle is atan of minus the slope of a least-squares line h = a - b r over that range, fitted to the
    points of all sectors together (the angle quoted), and to each sector alone (mean and standard deviation
    over the 8 sectors: the spread);
  * a second, cruder angle: atan(H / R_toe), the cone through the apex and the toe, R_toe where the mean
    surface height falls below one grain diameter (it is lower than the fitted angle when the heap is a
    dome with a rounded top, as the heaps without rolling resistance are).
It also prints what says whether the heap has settled and stays on the floor: the largest and the 99th
percentile of the grain speeds |v| + |w| r, the total kinetic energy at the last snapshot, and the number of
grains farther from the axis than the floor's edge (FLOOR_EDGE) minus one grain radius.

It also prints the angle of the Zhou et al. (2002) correlation at each mu_r > 0 (zhou_2002_correlation).
The plot (--plot) has both angles against mu_r beside that correlation, the mean surface profiles h(r),
and a side view of each heap: the grains in a slab |y - y_c| < one diameter through the axis, with the
fitted lines.
"""

import argparse
import math
import sys

import h5py
import numpy as np

FLOOR_EDGE = 0.25  # m: radius of the disc of fixed floor spheres (make_scenes.py)
SECTORS = 8
LOW, HIGH = 0.25, 0.75  # the slope's middle part, as fractions of the heap height

GRAIN_DIAMETER_MM = 10.0  # the scenes' mean grain diameter


def zhou_2002_correlation(mu, rolling_length_mm, diameter_mm):
    """The angle of repose (degrees) of the correlation fitted to DEM piles of monosized spheres by Zhou,
    Xu, Yu and Zulli (2002, Powder Technology 125, 45-54), as quoted with its units by the Lethe DEM
    documentation (examples/dem/plate-discharge): 68.61 mu_pp^0.27 mu_pw^0.22 mur_pp^0.06 mur_pw^0.12 d^-0.2,
    the rolling friction coefficients mur as lengths in mm (torque mur f_n) and d in mm. Our floor is made
    of the grains' own spheres, so the particle-wall coefficients are the particle-particle ones. It has
    no value at mur = 0 (the power law goes to 0)."""
    return 68.61 * mu**0.27 * mu**0.22 * rolling_length_mm**0.06 * rolling_length_mm**0.12 * diameter_mm**-0.2


def published_points(mu, rolling_values):
    """(label, mu_r, angle) of the Zhou et al. (2002) correlation at rubble's mu_r, converted to a length two
    ways: mu_r r_eff (r_eff = d/4 for two equal spheres: rubble's own torque bound) and mu_r d (the
    conversion the Lethe documentation uses)."""
    points = []
    for mu_r in rolling_values:
        if mu_r <= 0:
            continue
        points.append(("Zhou et al. 2002 correlation, length = mu_r r_eff", mu_r,
                       zhou_2002_correlation(mu, mu_r * GRAIN_DIAMETER_MM / 4, GRAIN_DIAMETER_MM)))
        points.append(("Zhou et al. 2002 correlation, length = mu_r d", mu_r,
                       zhou_2002_correlation(mu, mu_r * GRAIN_DIAMETER_MM, GRAIN_DIAMETER_MM)))
    return points


def read_last_snapshot(path):
    """Positions, velocities, angular velocities and radii of the grains in play at the last snapshot."""
    with h5py.File(path, "r") as f:
        names = sorted(f["snapshots"])
        snap = f["snapshots"][names[-1]]
        x = snap["position"][:]
        v = snap["velocity"][:]
        w = snap["angular_velocity"][:]
        t = float(snap.attrs["time"])
        mass = f["model/mass"][:]
        radius = f["model/radius"][:]
        kind = f["model/body_shape_kind"][:]
        rolling = f["model/contact_laws/rolling_friction"][:]
        friction = f["model/contact_laws/friction"][:]
        status = f["run"].attrs.get("status", b"?")
        reason = f["run"].attrs.get("stop_reason", b"?")
        floor_top = float(np.max(x[(mass == 0) & (kind == 0), 2] + radius[(mass == 0) & (kind == 0)]))
    grains = (mass > 0) & (kind == 0) & np.isfinite(x[:, 0])
    decode = lambda s: s.decode() if isinstance(s, bytes) else str(s)
    return {
        "x": x[grains], "v": v[grains], "w": w[grains], "r": radius[grains], "m": mass[grains], "t": t,
        "mu_r": float(rolling.max()), "mu": float(friction.max()), "floor_top": floor_top,
        "status": decode(status), "reason": decode(reason),
    }


def fit_line(r, h):
    """Least squares h = a + s r; returns (a, s)."""
    s, a = np.polyfit(r, h, 1)
    return a, s


def measure(run):
    x, rad = run["x"], run["r"]
    d = 2.0 * rad.mean()
    centre = x[:, :2].mean(axis=0)
    rel = x[:, :2] - centre
    rho = np.hypot(rel[:, 0], rel[:, 1])
    phi = np.arctan2(rel[:, 1], rel[:, 0])
    top = x[:, 2] + rad - run["floor_top"]  # height of each grain's top above the floor's top
    sector = ((phi + math.pi) / (2 * math.pi) * SECTORS).astype(int) % SECTORS
    nbins = int(math.ceil(rho.max() / d)) + 1
    rbin = (rho / d).astype(int)
    h = np.full((SECTORS, nbins), np.nan)
    for s in range(SECTORS):
        for b in range(nbins):
            sel = (sector == s) & (rbin == b)
            if sel.any():
                h[s, b] = top[sel].max()
    r_mid = (np.arange(nbins) + 0.5) * d
    mean_h = np.nanmean(np.where(np.isnan(h), 0.0, h), axis=0)  # an empty bin is the bare floor
    height = mean_h.max()  # the apex: the innermost bin holds few grains, so not always the highest
    apex = int(np.argmax(mean_h))
    # The toe: where the surface, going outwards from the apex, first falls below one grain diameter
    # above the floor (linear between bin centres): beyond it lie single grains in the floor's hollows,
    # whose tops stand about 0.6 d above the floor spheres' tops. atan(H / R_toe) is the angle of the
    # cone through apex and toe.
    below = np.nonzero(mean_h[apex:] < d)[0]
    t = apex + below[0] if below.size else nbins - 1
    f = (mean_h[t - 1] - d) / (mean_h[t - 1] - mean_h[t]) if mean_h[t - 1] > mean_h[t] else 0.0
    r_toe = r_mid[t - 1] + f * d
    # The middle part: from the first bin below HIGH*H to the last bin above LOW*H, outwards from the axis.
    inside = np.nonzero((mean_h <= HIGH * height) & (np.arange(nbins) > apex))[0]
    first = inside[0] if inside.size else apex
    outside = np.nonzero(mean_h >= LOW * height)[0]
    last = outside[outside >= first].max() if (outside >= first).any() else nbins - 1
    cols = np.arange(first, last + 1)
    pts_r, pts_h, sector_angles = [], [], []
    for s in range(SECTORS):
        ok = cols[~np.isnan(h[s, cols])]
        pts_r.append(r_mid[ok])
        pts_h.append(h[s, ok])
        if ok.size >= 3:
            _, slope = fit_line(r_mid[ok], h[s, ok])
            sector_angles.append(math.degrees(math.atan(-slope)))
    all_r, all_h = np.concatenate(pts_r), np.concatenate(pts_h)
    a, slope = fit_line(all_r, all_h)
    speed = np.linalg.norm(run["v"], axis=1) + np.linalg.norm(run["w"], axis=1) * rad
    inertia = 0.4 * run["m"] * rad**2
    kinetic = 0.5 * np.sum(run["m"] * np.sum(run["v"] ** 2, axis=1)) + 0.5 * np.sum(
        inertia * np.sum(run["w"] ** 2, axis=1))
    return {
        "angle": math.degrees(math.atan(-slope)), "sector_mean": float(np.mean(sector_angles)),
        "sector_std": float(np.std(sector_angles, ddof=1)), "sectors": len(sector_angles),
        "cone_angle": math.degrees(math.atan(height / r_toe)), "r_toe": r_toe,
        "height": height, "fit_from": r_mid[first], "fit_to": r_mid[last], "intercept": a, "slope": slope,
        "radius_extent": float(np.percentile(rho, 99)), "max_rho": float(rho.max()), "d": d,
        "beyond_floor": int(np.sum(rho > FLOOR_EDGE - rad)), "v_max": float(speed.max()),
        "v_p99": float(np.percentile(speed, 99)), "kinetic": float(kinetic), "grains": len(rad),
        "centre": centre, "profile": (r_mid, h, mean_h),
    }


def draw(runs, results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(runs)
    fig = plt.figure(figsize=(4.2 * n, 7.5))
    grid = fig.add_gridspec(2, n, height_ratios=[1.6, 1.0])
    ax = fig.add_subplot(grid[0, : n // 2])
    mu_r = [run["mu_r"] for run in runs]
    ax.errorbar(mu_r, [res["angle"] for res in results], yerr=[res["sector_std"] for res in results],
                fmt="o-", color="k", capsize=4,
                label="rubble: fit of the slope's middle part (bar: spread over 8 sectors)")
    ax.plot(mu_r, [res["cone_angle"] for res in results], "o--", color="k", mfc="white",
            label="rubble: cone through apex and toe, atan(H / R_toe)")
    top = max(m for m in mu_r) * 1.1
    curve = np.linspace(0.005, top, 100)
    ax.plot(curve, [zhou_2002_correlation(runs[0]["mu"], m * GRAIN_DIAMETER_MM / 4, GRAIN_DIAMETER_MM)
                    for m in curve], "b-", label="Zhou et al. 2002 correlation, rolling length = mu_r r_eff")
    ax.plot(curve, [zhou_2002_correlation(runs[0]["mu"], m * GRAIN_DIAMETER_MM, GRAIN_DIAMETER_MM)
                    for m in curve], "g-", label="Zhou et al. 2002 correlation, rolling length = mu_r d")
    ax.set_xlabel("rolling resistance mu_r (torque <= mu_r r_eff f_n)")
    ax.set_ylabel("angle of repose (degrees)")
    ax.set_title(f"Poured heaps of {results[0]['grains']} spheres, mu = {runs[0]['mu']:g}, e_n = 0")
    ax.set_xlim(-0.01, top)
    ax.set_ylim(0, 45)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    prof = fig.add_subplot(grid[0, n // 2:])
    for run, res in zip(runs, results):
        r_mid, _, mean_h = res["profile"]
        prof.plot(r_mid * 100, mean_h * 100, "o-", ms=3, label=f"mu_r = {run['mu_r']:g}")
    prof.set_xlabel("distance from the heap's axis (cm)")
    prof.set_ylabel("surface height, mean over 8 sectors (cm)")
    prof.set_title("Surface profiles h(r): highest grain top per radial bin of one diameter")
    prof.set_xlim(0, 20)
    prof.grid(alpha=0.3)
    prof.legend(fontsize=8)
    for k, (run, res) in enumerate(zip(runs, results)):
        side = fig.add_subplot(grid[1, k])
        rel = run["x"][:, :2] - res["centre"]
        slab = np.abs(rel[:, 1]) < res["d"]
        z = run["x"][slab, 2] - run["floor_top"]
        side.scatter(rel[slab, 0] * 100, z * 100, s=(run["r"][slab] / res["d"] * 7) ** 2, c="tab:orange",
                     edgecolors="k", linewidths=0.3, label=f"grains with |y| < d ({slab.sum()})")
        rr = np.linspace(res["fit_from"], res["fit_to"], 10)
        for sign in (-1, 1):
            side.plot(sign * rr * 100, (res["intercept"] + res["slope"] * rr) * 100, "b-", lw=2,
                      label="fitted surface" if sign > 0 else None)
        side.axhline(0, color="gray", lw=1)
        side.set_aspect("equal")
        side.set_xlim(-20, 20)
        side.set_ylim(-1, 12)
        side.set_xlabel("x (cm, from the heap's axis)")
        side.set_ylabel("height above the floor (cm)")
        side.set_title(f"mu_r = {run['mu_r']:g}: fit {res['angle']:.1f} deg "
                       f"({res['sector_mean']:.1f} +- {res['sector_std']:.1f}), cone {res['cone_angle']:.1f} deg",
                       fontsize=9)
        side.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+", help="run files (run.h5)")
    parser.add_argument("--plot", help="write the figure here (PNG)")
    parser.add_argument("--csv", help="write the table here")
    args = parser.parse_args(argv)
    runs = [read_last_snapshot(p) for p in args.runs]
    order = np.argsort([run["mu_r"] for run in runs])
    runs = [runs[i] for i in order]
    paths = [args.runs[i] for i in order]
    results = [measure(run) for run in runs]
    header = ("mu_r", "angle_deg", "sector_mean_deg", "sector_std_deg", "cone_deg", "height_m", "r_toe_m",
              "fit_from_m", "fit_to_m",
              "r99_m", "r_max_m", "beyond_floor", "t_s", "v_max_m_s", "v_p99_m_s", "kinetic_J", "grains", "status")
    rows = []
    for path, run, res in zip(paths, runs, results):
        rows.append((f"{run['mu_r']:g}", f"{res['angle']:.1f}", f"{res['sector_mean']:.1f}",
                     f"{res['sector_std']:.1f}", f"{res['cone_angle']:.1f}", f"{res['height']:.4f}",
                     f"{res['r_toe']:.3f}", f"{res['fit_from']:.3f}",
                     f"{res['fit_to']:.3f}", f"{res['radius_extent']:.3f}", f"{res['max_rho']:.3f}",
                     str(res["beyond_floor"]),
                     f"{run['t']:.3f}", f"{res['v_max']:.2e}", f"{res['v_p99']:.2e}", f"{res['kinetic']:.2e}",
                     str(res["grains"]), run["status"]))
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    print("  ".join(h.rjust(w) for h, w in zip(header, widths)))
    for r in rows:
        print("  ".join(c.rjust(w) for c, w in zip(r, widths)))
    for path, run in zip(paths, runs):
        print(f"{path}: {run['reason']}")
    for label, mr, angle in published_points(runs[0]["mu"], [run["mu_r"] for run in runs]):
        print(f"mu_r = {mr:g}: {label}: {angle:.1f} deg")
    if args.csv:
        with open(args.csv, "w", encoding="utf-8") as f:
            f.write(",".join(header) + "\n")
            for r in rows:
                f.write(",".join(r) + "\n")
    if args.plot:
        draw(runs, results, args.plot)
        print("wrote", args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
