#!/usr/bin/python3
"""Spin-up to failure of a 1 000-sphere aggregate: measures each stage and compares the failure
spin with the Drucker-Prager limit of a self-gravitating sphere (Holsapple 2007).

    spin_up.py reference ACCRETION_RUN          aggregate properties of the settled aggregate
    spin_up.py end-time RUN                     the simulated time at which RUN ended, s
    spin_up.py predict ACCRETION_RUN MU F_C     the closed-form limit spin omega_H, rad/s (places the stages)
    spin_up.py axis ACCRETION_RUN               the settled aggregate's axis of largest moment of inertia
                                                (the spin axis: rotation about it is stable), "x, y, z"
    spin_up.py check STAGE_RUN ACCRETION_RUN --spin W
                                                exit 0 while the aggregate holds, 10 once it has failed
                                                (W: the spin given so far, rad/s; written to STAGE_RUN/stage.json)
    spin_up.py analyse RUNS_DIR [--png FILE] [--markdown FILE]
                                                table of every series, failure spins, ratios, plot

RUN arguments are run folders written by `rubble run` (their run.h5). The method, the failure
criterion and the closed form are explained in README.md next to this file.
"""
import argparse
import json
import math
import os
import sys

os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
import h5py  # noqa: E402
import numpy as np  # noqa: E402

G = 6.674e-11  # m^3 kg^-1 s^-2, as rubble's default [gravity] G

# Failure thresholds (README.md, "Failure criterion").
SHED_GRAINS = 1  # a grain whose centre is beyond R_out + d_max of the centre of mass is shed
FLATTENING_CHANGE = 0.02  # change of the equivalent ellipsoid's c/a since the settled state
NON_RIGID_RMS = 0.1  # RMS non-rigid displacement over one stage, in mean grain diameters


def load_state(run_dir, snapshot=-1):
    """Positions, velocities, angular velocities, radii, masses and contacts of one snapshot."""
    with h5py.File(os.path.join(run_dir, "run.h5"), "r") as f:
        keys = sorted(f["snapshots"].keys())
        g = f["snapshots"][keys[snapshot]]
        state = {
            "time": float(g.attrs["time"]),
            "x": g["position"][:],
            "v": g["velocity"][:],
            "w": g["angular_velocity"][:],
            "a": g["contact_body_a"][:],
            "b": g["contact_body_b"][:],
            "status": g["contact_status"][:],
            "impulse": g["contact_impulse"][:],
            "r": f["model/radius"][:],
            "m": f["model/mass"][:],
            "density": float(f["model/materials/density"][0]),
            "cohesion": float(f["model/contact_laws/cohesion"][0, 0]),
            "friction": float(f["model/contact_laws/friction"][0, 0]),
            "snapshots": len(keys),
        }
    return state


def centre_of_mass(x, m, cut=None):
    """Centre of mass of the grains within `cut` of it (iterated), or of all grains."""
    c = np.average(x, axis=0, weights=m)
    if cut is None:
        return c, np.ones(len(m), bool)
    for _ in range(10):
        inside = np.linalg.norm(x - c, axis=1) <= cut
        c = np.average(x[inside], axis=0, weights=m[inside])
    return c, np.linalg.norm(x - c, axis=1) <= cut


def shape(x, m, r, c, inside):
    """Inertia of the aggregate about c and its equivalent homogeneous ellipsoid."""
    y = x[inside] - c
    mm, rr = m[inside], r[inside]
    inertia = np.eye(3) * (np.sum(mm * np.sum(y * y, axis=1)) + np.sum(0.4 * mm * rr**2))
    inertia -= np.einsum("i,ij,ik->jk", mm, y, y)
    moments, axes = np.linalg.eigh(inertia)  # I1 <= I2 <= I3
    mass = mm.sum()
    i1, i2, i3 = moments
    # Homogeneous ellipsoid: I_a = M (b^2 + c^2) / 5, ... => a^2 = 5 (I2 + I3 - I1) / (2 M).
    semi = np.sqrt(5.0 / (2.0 * mass) * np.array([i2 + i3 - i1, i1 + i3 - i2, i1 + i2 - i3]))
    return inertia, moments, axes, semi, mass


def aggregate(state, r_out0=None, d_max=None):
    """The aggregate's properties at one state (r_out0, d_max from the settled aggregate)."""
    x, m, r = state["x"], state["m"], state["r"]
    grains = m > 0
    x, m, r = x[grains], m[grains], r[grains]
    if r_out0 is None:
        c, inside = centre_of_mass(x, m)
        r_out0 = float(np.max(np.linalg.norm(x - c, axis=1) + r))
        d_max = float(2 * r.max())
    cut = r_out0 + d_max
    c, inside = centre_of_mass(x, m, cut)
    inertia, moments, axes, semi, mass = shape(x, m, r, c, inside)
    a, b, cc = semi  # a >= b >= c
    radius = float(np.cbrt(a * b * cc))  # volume-equivalent radius of the equivalent ellipsoid
    bulk_density = mass / (4.0 / 3.0 * math.pi * radius**3)
    # Spin: angular momentum about c over the inertia tensor (the rigid-body rate).
    y = x - c
    L = np.sum(m[:, None] * np.cross(y, state["v"][grains]), axis=0)
    L += np.sum((0.4 * m * r**2)[:, None] * state["w"][grains], axis=0)
    total_inertia = np.eye(3) * (np.sum(m * np.sum(y * y, axis=1)) + np.sum(0.4 * m * r**2))
    total_inertia -= np.einsum("i,ij,ik->jk", m, y, y)
    omega = np.linalg.solve(total_inertia, L)
    # Coordination (force-carrying contacts) and packing fraction of the interior, for Rumpf's
    # relation: grains whose centre lies within 0.8 R of the centre.
    interior = np.linalg.norm(y, axis=1) <= 0.8 * radius
    ids = np.flatnonzero(grains)
    index = -np.ones(len(state["m"]), int)
    index[ids] = np.arange(len(ids))
    carrying = state["status"] != 0
    count = np.zeros(len(ids))
    for body in (state["a"][carrying], state["b"][carrying]):
        k = index[body]
        np.add.at(count, k[k >= 0], 1)
    z_interior = float(count[interior].mean())
    volume = 4.0 / 3.0 * math.pi * r**3
    packing = float(volume[inside].sum() / (4.0 / 3.0 * math.pi * radius**3))
    return {
        "time": state["time"],
        "mass": float(mass),
        "grains": int(len(m)),
        "shed": int(np.sum(~inside)),
        "r_out0": r_out0,
        "d_max": d_max,
        "d_mean": float(2 * r.mean()),
        "d2_mean": float(np.mean((2 * r) ** 2)),
        "semi_axes": [float(s) for s in semi],
        "c_over_a": float(cc / a),
        "b_over_a": float(b / a),
        "radius": radius,
        "bulk_density": float(bulk_density),
        "packing": packing,
        "z_interior": z_interior,
        "z_all": float(count.mean()),
        "omega": [float(o) for o in omega],
        "largest_moment_axis": [float(v) for v in axes[:, 2]],
        "spin_off_axis_deg": float(math.degrees(math.acos(min(1.0, abs(axes[:, 2] @ omega) / max(np.linalg.norm(omega), 1e-300))))),
        "centre": [float(v) for v in c],
    }


def non_rigid_rms(first, last, inside):
    """RMS displacement left after the best rigid motion (Kabsch 1976) between two states."""
    p, q = first[inside], last[inside]
    p0, q0 = p - p.mean(axis=0), q - q.mean(axis=0)
    u, _, vt = np.linalg.svd(p0.T @ q0)
    d = np.sign(np.linalg.det(u @ vt))
    rotation = u @ np.diag([1, 1, d]) @ vt
    return float(np.sqrt(np.mean(np.sum((p0 @ rotation - q0) ** 2, axis=1))))


def reference(acc_run):
    return aggregate(load_state(acc_run))


def stage(stage_run, ref):
    """One stage's end state against the settled aggregate `ref`."""
    last = load_state(stage_run)
    first = load_state(stage_run, 0)
    agg = aggregate(last, ref["r_out0"], ref["d_max"])
    grains = last["m"] > 0
    c, inside = centre_of_mass(last["x"][grains], last["m"][grains], ref["r_out0"] + ref["d_max"])
    agg["non_rigid_rms_d"] = non_rigid_rms(first["x"][grains], last["x"][grains], inside) / ref["d_mean"]
    agg["flattening_change"] = ref["c_over_a"] - agg["c_over_a"]
    agg["cohesion"] = last["cohesion"]
    agg["friction"] = last["friction"]
    agg["failed_shed"] = agg["shed"] >= SHED_GRAINS
    agg["failed_deform"] = abs(agg["flattening_change"]) > FLATTENING_CHANGE or agg["non_rigid_rms_d"] > NON_RIGID_RMS
    agg["failed"] = agg["failed_shed"] or agg["failed_deform"]
    return agg


# ---------------------------------------------------------------- the closed form (README.md)
def drucker_prager(phi):
    """Holsapple (2007)'s Drucker-Prager constants s and k/Y for a friction angle phi (rad):
    the cone through the compression meridian of Mohr-Coulomb."""
    sphi = math.sin(phi)
    s = 2 * sphi / (math.sqrt(3) * (3 - sphi))
    k_over_y = 6 * math.cos(phi) / (math.sqrt(3) * (3 - sphi))
    return s, k_over_y


def holsapple_sphere_spin(phi, tensile_strength, bulk_density, radius):
    """Limit spin (rad/s) of a homogeneous self-gravitating sphere by the volume-averaged
    Drucker-Prager criterion sqrt(J2) <= k - s I1, with k = 3 s sigma_t (the cone's apex at the
    hydrostatic tensile strength sigma_t): omega^2 = 3 s (g0 + sigma_t / q) / (1/sqrt(3) + 2 s),
    g0 = 4/3 pi G rho, q = rho R^2 / 5."""
    s, _ = drucker_prager(phi)
    g0 = 4.0 / 3.0 * math.pi * G * bulk_density
    q = bulk_density * radius**2 / 5.0
    return math.sqrt(3 * s * (g0 + tensile_strength / q) / (1 / math.sqrt(3) + 2 * s))


def rumpf_tensile_strength(pull_off, packing, coordination, diameter2):
    """Rumpf (1962): the isotropic tensile stress of a packing whose contacts all pull at F_c,
    sigma_t = phi Z F_c / (pi d^2) (with d^2 the mean square diameter of a polydisperse packing)."""
    return packing * coordination * pull_off / (math.pi * diameter2)


def implied_friction_angle(spin, bulk_density, radius):
    """The friction angle phi* for which the cohesionless closed form gives `spin` (bisection);
    None when `spin` is at or above the orbital limit sqrt(g0), which no phi reaches."""
    lo, hi = 1e-6, math.radians(89.999)
    if spin >= holsapple_sphere_spin(hi, 0.0, bulk_density, radius):
        return None
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if holsapple_sphere_spin(mid, 0.0, bulk_density, radius) < spin:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def friction_angle(mu):
    """The aggregate's friction angle taken from the contact friction: phi = atan(mu)."""
    return math.atan(mu)


# ---------------------------------------------------------------- commands
def cmd_reference(args):
    print(json.dumps(reference(args.run), indent=1))


def cmd_end_time(args):
    with h5py.File(os.path.join(args.run, "run.h5"), "r") as f:
        print(repr(float(f["series/time"][-1])))


def cmd_predict(args):
    ref = reference(args.run)
    sigma_t = rumpf_tensile_strength(args.pull_off, ref["packing"], ref["z_interior"], ref["d2_mean"])
    print(repr(holsapple_sphere_spin(friction_angle(args.mu), sigma_t, ref["bulk_density"], ref["radius"])))


def cmd_axis(args):
    axis = np.array(reference(args.run)["largest_moment_axis"])
    axis *= np.sign(axis[np.argmax(np.abs(axis))])  # the component of largest size positive
    print(", ".join(f"{v:.6f}" for v in axis))


def cmd_check(args):
    ref = reference(args.reference)
    agg = stage(args.run, ref)
    agg["spin"] = args.spin
    w = np.linalg.norm(agg["omega"])
    print(
        f"{args.run}: omega = {w:.4e} rad/s (period {2 * math.pi / w / 3600:.3f} h), shed {agg['shed']}, "
        f"c/a {agg['c_over_a']:.4f} (settled {ref['c_over_a']:.4f}), non-rigid RMS {agg['non_rigid_rms_d']:.4f} d, "
        f"spin {agg['spin_off_axis_deg']:.1f} deg off the largest-moment axis"
        f" -> {'FAILED' if agg['failed'] else 'holds'}"
    )
    with open(os.path.join(args.run, "stage.json"), "w") as out:
        json.dump(agg, out, indent=1)
    sys.exit(10 if agg["failed"] else 0)


def series_of(runs_dir):
    """{(mu, cohesion label): [stage folders in order]} from RUNS_DIR/spin-mu*-c*-NN."""
    series = {}
    for name in sorted(os.listdir(runs_dir)):
        if name.startswith("spin-") and os.path.exists(os.path.join(runs_dir, name, "stage.json")):
            key = name.rsplit("-", 1)[0]
            series.setdefault(key, []).append(os.path.join(runs_dir, name))
    return series


def cmd_analyse(args):
    rows = []
    for key, folders in sorted(series_of(args.runs).items()):
        mu = float(key.split("-mu")[1].split("-")[0])
        ref = reference(os.path.join(args.runs, f"accretion-mu{mu}"))
        stages = sorted((json.load(open(os.path.join(d, "stage.json"))) for d in folders), key=lambda s: s["spin"])
        spins = [s["spin"] for s in stages]
        held = [s["spin"] for s in stages if not s["failed"]]
        failed = [k for k, s in enumerate(stages) if s["failed"]]
        k = failed[0] if failed else None
        pull_off = stages[0]["cohesion"]
        sigma_t = rumpf_tensile_strength(pull_off, ref["packing"], ref["z_interior"], ref["d2_mean"])
        phi = friction_angle(mu)
        predicted = holsapple_sphere_spin(phi, sigma_t, ref["bulk_density"], ref["radius"])
        row = {
            "series": key,
            "mu": mu,
            "cohesion_N": pull_off,
            "sigma_t_Pa": sigma_t,
            "stages": len(stages),
            "holds_up_to": max((w for w in held if k is None or w < spins[k]), default=0.0),
            "fails_at": spins[k] if k is not None else None,
            "mode": (("shedding" if stages[k]["failed_shed"] else "") + (" deformation" if stages[k]["failed_deform"] else "")).strip() if k is not None else "none",
            "holsapple": predicted,
            "phi_deg": math.degrees(phi),
            "stage_rows": [dict(spin=w, **{n: s[n] for n in ("shed", "c_over_a", "non_rigid_rms_d", "failed")}) for w, s in zip(spins, stages)],
        }
        # The same bracket by shedding and the shape (c/a) alone, without the non-rigid displacement
        # (which also counts the creep of a pile not fully at rest: README.md, "Results").
        shape_failed = [s["failed_shed"] or abs(s["flattening_change"]) > FLATTENING_CHANGE for s in stages]
        ks = shape_failed.index(True) if True in shape_failed else None
        row["shape_bracket"] = [
            max((w for w, f in zip(spins, shape_failed) if not f and (ks is None or w < spins[ks])), default=0.0),
            spins[ks] if ks is not None else None,
        ]
        if k is not None and row["holds_up_to"] == 0.0:
            row["ratio_below"] = spins[k] / predicted  # failed at every spin tried: an upper bound
        elif k is not None:
            lo = row["holds_up_to"]
            row["omega_f"] = 0.5 * (lo + spins[k])
            row["ratio"] = row["omega_f"] / predicted
            row["ratio_range"] = [lo / predicted, spins[k] / predicted]
        rows.append(row)
    for row in rows:  # phi* from the cohesionless failure of the same mu, and the ratio with it
        base = [r for r in rows if r["mu"] == row["mu"] and r["cohesion_N"] == 0.0 and "omega_f" in r]
        ref = reference(os.path.join(args.runs, f"accretion-mu{row['mu']}"))
        phi_star = implied_friction_angle(base[0]["omega_f"], ref["bulk_density"], ref["radius"]) if base else None
        row["phi_star_deg"] = math.degrees(phi_star) if phi_star else None
        if phi_star and "omega_f" in row:
            row["holsapple_phi_star"] = holsapple_sphere_spin(phi_star, row["sigma_t_Pa"], ref["bulk_density"], ref["radius"])
            row["ratio_phi_star"] = row["omega_f"] / row["holsapple_phi_star"]
    text = markdown(rows, args.runs)
    print(text)
    if args.markdown:
        open(args.markdown, "w").write(text)
    if args.png:
        plot(rows, args.runs, args.png)


def markdown(rows, runs):
    refs = {mu: reference(os.path.join(runs, f"accretion-mu{mu}")) for mu in sorted({r["mu"] for r in rows})}
    out = ["| μ | R (m) | ρ_b (kg/m³) | packing φ | Z (interior) | c/a | √g0 (rad/s) |", "|---|---|---|---|---|---|---|"]
    for mu, ref in refs.items():
        g0 = 4 / 3 * math.pi * G * ref["bulk_density"]
        out.append(f"| {mu} | {ref['radius']:.2f} | {ref['bulk_density']:.0f} | {ref['packing']:.3f} | {ref['z_interior']:.2f} | {ref['c_over_a']:.3f} | {math.sqrt(g0):.3e} |")
    out += [
        "",
        "| μ | F_c (N) | σ_t (Pa) | holds at ω (rad/s) | fails at ω (rad/s) | mode | ω_f (rad/s) | period (h) | ω_H, φ = atan μ (rad/s) | ω_f / ω_H (bracket) | φ* | ω_f / ω_H(φ*) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        star = f"{r['phi_star_deg']:.1f}°" if r.get("phi_star_deg") else "—"
        if "omega_f" in r:
            out.append(
                f"| {r['mu']} | {r['cohesion_N']:.0f} | {r['sigma_t_Pa']:.2f} | {r['holds_up_to']:.3e} | {r['fails_at']:.3e} | {r['mode']} | {r['omega_f']:.3e} | "
                f"{2 * math.pi / r['omega_f'] / 3600:.2f} | {r['holsapple']:.3e} | {r['ratio']:.2f} ({r['ratio_range'][0]:.2f}–{r['ratio_range'][1]:.2f}) | {star} | "
                + (f"{r['ratio_phi_star']:.2f}" if "ratio_phi_star" in r else "—")
                + " |"
            )
        elif "ratio_below" in r:
            out.append(
                f"| {r['mu']} | {r['cohesion_N']:.0f} | {r['sigma_t_Pa']:.2f} | — | {r['fails_at']:.3e} | {r['mode']} | < {r['fails_at']:.3e} | > {2 * math.pi / r['fails_at'] / 3600:.2f} | "
                f"{r['holsapple']:.3e} | < {r['ratio_below']:.2f} | — | — |"
            )
        else:
            out.append(f"| {r['mu']} | {r['cohesion_N']:.0f} | {r['sigma_t_Pa']:.2f} | {r['holds_up_to']:.3e} | — | no failure | — | — | {r['holsapple']:.3e} | > {r['holds_up_to'] / r['holsapple']:.2f} | {star} | — |")
    out += ["", "By shedding and c/a alone (no non-rigid displacement criterion): ω_f / ω_H brackets:", ""]
    for r in rows:
        lo, hi = r["shape_bracket"]
        out.append(f"- {r['series']}: holds at {lo / r['holsapple']:.2f}, " + (f"fails at {hi / r['holsapple']:.2f}" if hi else "no failure"))
    out += ["", "Stages (spin at the end of the stage: grains shed, c/a, RMS non-rigid displacement in mean diameters):", ""]
    for r in rows:
        cells = ", ".join(f"{s['spin']:.1e}: {s['shed']}/{s['c_over_a']:.3f}/{s['non_rigid_rms_d']:.3f}{' F' if s['failed'] else ''}" for s in r["stage_rows"])
        out.append(f"- {r['series']}: {cells}")
    return "\n".join(out) + "\n"


def plot(rows, runs, png):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    colours = {0.2: "tab:blue", 0.6: "tab:red"}
    for mu in sorted({r["mu"] for r in rows}):
        ref = reference(os.path.join(runs, f"accretion-mu{mu}"))
        sig = np.linspace(0, 1.1 * max(r["sigma_t_Pa"] for r in rows), 200)
        curve = [holsapple_sphere_spin(friction_angle(mu), s, ref["bulk_density"], ref["radius"]) for s in sig]
        ax.plot(sig, 1e3 * np.array(curve), color=colours.get(mu, "k"), label=f"Holsapple DP sphere, φ = atan {mu} = {math.degrees(friction_angle(mu)):.0f}°")
        stars = [r["phi_star_deg"] for r in rows if r["mu"] == mu and r.get("phi_star_deg")]
        if stars:
            curve = [holsapple_sphere_spin(math.radians(stars[0]), s, ref["bulk_density"], ref["radius"]) for s in sig]
            ax.plot(sig, 1e3 * np.array(curve), color=colours.get(mu, "k"), ls="--", lw=0.9, label=f"same, φ* = {stars[0]:.0f}° (fits μ = {mu}, F_c = 0)")
        for r in rows:
            if r["mu"] != mu:
                continue
            if "omega_f" in r:
                ax.errorbar(r["sigma_t_Pa"], 1e3 * r["omega_f"], yerr=1e3 * 0.5 * (r["fails_at"] - r["holds_up_to"]), fmt="o", color=colours.get(mu, "k"), capsize=3)
            elif "ratio_below" in r:  # failed at every spin tried
                ax.plot(r["sigma_t_Pa"], 1e3 * r["fails_at"], "v", color=colours.get(mu, "k"), mfc="none")
                lo, hi = r["shape_bracket"]
                if lo > 0 and hi:  # the bracket by shedding and shape alone
                    ax.errorbar(r["sigma_t_Pa"] + 0.05, 0.5e3 * (lo + hi), yerr=0.5e3 * (hi - lo), fmt="s", mfc="none", color=colours.get(mu, "k"), capsize=3)
            else:  # held at every spin tried
                ax.plot(r["sigma_t_Pa"], 1e3 * r["holds_up_to"], "^", color=colours.get(mu, "k"), mfc="none")
        g0 = 4 / 3 * math.pi * G * ref["bulk_density"]
        ax.axhline(1e3 * math.sqrt(g0), color=colours.get(mu, "k"), ls=":", lw=0.8)
    ax.set_xlabel("bulk tensile strength σ_t = φ Z F_c / (π ⟨d²⟩), Pa (Rumpf 1962)")
    ax.set_ylabel("failure spin ω_f, 10⁻³ rad/s")
    ax.set_title("Spin-up to failure, 1 000 spheres (points: rubble; lines: closed form)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    ax.text(0.98, 0.02, "dotted: orbital limit √(4πGρ_b/3); bars: last spin held to first failed;\n▽: failed at the lowest spin tried (an upper bound); □: bracket by shedding and c/a alone", transform=ax.transAxes, ha="right", fontsize=6.5)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    a = sub.add_parser("reference")
    a.add_argument("run")
    a.set_defaults(func=cmd_reference)
    a = sub.add_parser("end-time")
    a.add_argument("run")
    a.set_defaults(func=cmd_end_time)
    a = sub.add_parser("predict")
    a.add_argument("run")
    a.add_argument("mu", type=float)
    a.add_argument("pull_off", type=float)
    a.set_defaults(func=cmd_predict)
    a = sub.add_parser("axis")
    a.add_argument("run")
    a.set_defaults(func=cmd_axis)
    a = sub.add_parser("check")
    a.add_argument("run")
    a.add_argument("reference")
    a.add_argument("--spin", type=float, required=True)
    a.set_defaults(func=cmd_check)
    a = sub.add_parser("analyse")
    a.add_argument("runs")
    a.add_argument("--png")
    a.add_argument("--markdown")
    a.set_defaults(func=cmd_analyse)
    args = p.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
