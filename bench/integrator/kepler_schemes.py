#!/usr/bin/python3
"""Energy error of a Kepler orbit (e = 0.5) under the two ways of taking the smooth force in a
Moreau-Jean theta = 1/2 step, written out from their formulas (core/integrator.hpp):

  start-of-step force (rubble before 2026-11-24):  v+ = v + h a(x);  x+ = x + h (v + v+) / 2
  Moreau's midpoint form (now):                    x_m = x + h v / 2;  v+ = v + h a(x_m);  x+ = x_m + h v+ / 2

in units G M = 1, a = 1 (period 2 pi), started at apoapsis, 10 orbits. Prints a CSV row per step
size and the fitted slopes, and draws docs/orbit-energy-vs-step.png with the measured points of the
C++ code (tests/simulation/test_step.cpp, KeplerOrbit.*) beside the model.
Usage: /usr/bin/python3 bench/integrator/kepler_schemes.py [OUT.png]
"""
import math
import sys

import numpy as np


def run(steps_per_orbit, orbits, midpoint, e=0.5):
    period = 2.0 * math.pi
    h = period / steps_per_orbit
    x = np.array([1.0 + e, 0.0])
    v = np.array([0.0, math.sqrt((1.0 - e) / (1.0 + e))])

    def acc(p):
        r = math.hypot(p[0], p[1])
        return -p / (r * r * r)

    def energy(p, q):
        return 0.5 * (q @ q) - 1.0 / math.hypot(p[0], p[1])

    e0 = energy(x, v)
    worst = 0.0
    for _ in range(steps_per_orbit * orbits):
        if midpoint:
            xm = x + 0.5 * h * v
            vn = v + h * acc(xm)
            x = xm + 0.5 * h * vn
        else:
            vn = v + h * acc(x)
            x = x + 0.5 * h * (v + vn)
        v = vn
        worst = max(worst, abs(energy(x, v) - e0) / abs(e0))
    return worst


def main():
    steps = [250, 500, 1000, 2000, 4000]
    old = [run(n, 10, False) for n in steps]
    new = [run(n, 10, True) for n in steps]
    print("steps_per_orbit,start_of_step_force,midpoint")
    for n, a, b in zip(steps, old, new):
        print(f"{n},{a:.4e},{b:.4e}")
    h = np.log([2 * math.pi / n for n in steps])
    slope_old = np.polyfit(h, np.log(old), 1)[0]
    slope_new = np.polyfit(h, np.log(new), 1)[0]
    print(f"slope of log(error) vs log(h): start-of-step force {slope_old:.2f}, midpoint {slope_new:.2f}")
    out = sys.argv[1] if len(sys.argv) > 1 else "docs/orbit-energy-vs-step.png"
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.loglog(steps, old, "o-", label=f"force at the start of the step (slope {slope_old:.2f} in h)")
    ax.loglog(steps, new, "s-", label=f"Moreau's midpoint form (slope {slope_new:.2f} in h)")
    # The C++ code, tests/simulation/test_step.cpp (KeplerOrbit.EnergyErrorFallsAsTheSquareOfTheStep).
    ax.loglog([500, 1000, 2000], [1.127e-4, 2.818e-5, 7.044e-6], "k+", markersize=12, label="rubble (C++), midpoint")
    ax.set_xlabel("steps per orbit")
    ax.set_ylabel("largest relative energy error over 10 orbits")
    ax.set_title("Kepler orbit, e = 0.5, theta = 1/2")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
