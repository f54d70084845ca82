#!/usr/bin/env python3
"""Branch a finished aggregate into a friction sweep.

    /usr/bin/python3 examples/python/friction_sweep.py accretion-125-spheres-py --mu 0 0.2 0.5 1.0

Loads the newest checkpoint of a run folder (written by accretion.py, or by `rubble run`), spins
the aggregate up rigidly to a fraction of the critical spin rate omega_c = sqrt(G M / R^3) (R:
half of D_max), and for each friction coefficient runs a branch of the same state for the same
simulated time; prints how the aggregate responded: D_max, packing fraction, Z and the kinetic
energy left. Every branch starts from the same bits; only mu differs.
"""
import argparse
import math

import numpy as np

import rubble


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("run_folder", help="a run folder with checkpoints/ (accretion.py or rubble run)")
    parser.add_argument("--mu", type=float, nargs="+", default=[0.0, 0.2, 0.5, 1.0], help="friction coefficients")
    parser.add_argument("--spin", type=float, default=0.8, help="spin rate as a fraction of omega_c (default 0.8)")
    parser.add_argument("--duration", type=float, default=1.0,
                        help="simulated time of each branch, in spin periods (default 1)")
    args = parser.parse_args()

    base = rubble.Simulation.from_checkpoint(args.run_folder)
    grains = np.flatnonzero(base.is_grain)
    m = base.masses[grains]
    x = base.positions[grains]
    x_cm = (m[:, None] * x).sum(axis=0) / m.sum()
    before = base.metrics()
    radius = 0.5 * before["aggregate_diameter"]
    G = 6.674e-11
    omega_c = math.sqrt(G * m.sum() / radius ** 3)
    omega = np.array([0.0, 0.0, args.spin * omega_c])
    # Rigid rotation about the centre of mass: v = omega x (x - x_cm), every grain spinning at omega.
    base.velocities[grains] = np.cross(omega, x - x_cm)
    base.angular_velocities[grains] = omega
    period = 2 * math.pi / np.linalg.norm(omega)
    end = base.time + args.duration * period
    print(f"aggregate of {len(grains)} grains at t = {base.time:.0f} s: D_max = {before['aggregate_diameter']:.1f} m, "
          f"nu = {before['packing_fraction']:.3f}, Z = {before['coordination']:.2f}; spun to "
          f"{args.spin:g} omega_c = {omega[2]:.3e} rad/s (period {period:.0f} s), each branch runs to t = {end:.0f} s")

    print(f"{'mu':>5}  {'D_max (m)':>9}  {'nu':>6}  {'Z':>5}  {'Z_prime':>7}  {'E_k (J)':>10}  {'steps':>6}")
    materials = base.materials
    for mu in args.mu:
        branch = base.branch()
        for a in materials:
            for b in materials:
                branch.set_contact_law(a, b, friction=mu)
        summary = branch.run(until=end)
        after = branch.metrics()
        print(f"{mu:5.2f}  {after['aggregate_diameter']:9.1f}  {after['packing_fraction']:6.3f}  "
              f"{after['coordination']:5.2f}  {after['coordination_without_rattlers']:7.2f}  "
              f"{after['kinetic_energy']:10.3e}  {summary['steps']:6d}")


if __name__ == "__main__":
    main()
