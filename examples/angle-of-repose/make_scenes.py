#!/usr/bin/python3
"""Write the angle-of-repose scenes: heap-mur0.toml, heap-mur0.05.toml, heap-mur0.1.toml, heap-mur0.2.toml.

Each scene pours 2 000 glass spheres (radius 4.5-5.5 mm, uniform) from a small box above the centre
onto a rough floor: one layer of fixed (driven) spheres of radius 5 mm on a square lattice of
pitch 10.5 mm, each lifted or lowered at random by up to 1 mm, over a disc of radius 0.25 m (50
grain radii). The three scenes differ only by the rolling resistance mu_r of the sphere contacts
(docs/scene-file.md, [[contact_laws]]: torque <= mu_r r_eff f_n); Coulomb's mu = 0.5, e_n = 0 and
no twisting resistance in all three.

Usage: /usr/bin/python3 examples/angle-of-repose/make_scenes.py   (writes beside this script)
"""

import math
import os
import random

HERE = os.path.dirname(os.path.abspath(__file__))

GRAINS = 2000
RADIUS_MIN = 0.0045  # m
RADIUS_MAX = 0.0055  # m
FLOOR_RADIUS = 0.005  # m: floor spheres, the grains' mean size
FLOOR_PITCH = 0.0105  # m: square lattice; the hole between four floor spheres holds a grain
FLOOR_JITTER = 0.001  # m: each floor sphere's height drawn uniformly in +-this (a rough, not crystalline, floor)
FLOOR_EXTENT = 0.25  # m: floor disc radius, 50 grain radii (the mu_r = 0 heap spreads to about 40)
ROLLING = [0.0, 0.05, 0.1, 0.2]


def floor_spheres(seed=1):
    """Centres of the floor spheres: a square lattice clipped to a disc, heights jittered."""
    rng = random.Random(seed)
    n = int(FLOOR_EXTENT / FLOOR_PITCH)
    centres = []
    for i in range(-n, n + 1):
        for j in range(-n, n + 1):
            x, y = i * FLOOR_PITCH, j * FLOOR_PITCH
            if math.hypot(x, y) <= FLOOR_EXTENT:
                centres.append((x, y, rng.uniform(-FLOOR_JITTER, FLOOR_JITTER)))
    return centres


def scene_text(mu_r, floor):
    tag = f"mur{mu_r:g}"
    lines = [
        f"# rubble scene file: an angle-of-repose heap, rolling resistance mu_r = {mu_r:g}.",
        "# Written by examples/angle-of-repose/make_scenes.py (do not edit by hand; change the script).",
        f"# {GRAINS} glass spheres (radius 4.5-5.5 mm) are poured from a 5 cm x 5 cm box 13-20 cm above",
        "# the centre of a rough floor (one layer of fixed spheres of radius 5 mm, square lattice of",
        "# pitch 10.5 mm, heights +-1 mm at random, over a disc of radius 0.25 m) at 1 000 grains/s, and",
        "# form a heap. mu = 0.5, e_n = 0, no twisting resistance. The run stops when the grains are at",
        "# rest (speeds, coordination and contacts steady for 0.2 s) or at t = 3 s.",
        "# Measure with examples/angle-of-repose/measure.py (README.md there). SI units.",
        f'name = "heap-{tag}"',
        "seed = 1",
        "",
        "[time]",
        "dt = 1e-3          # s: 1/32 of sqrt(d/g); a grain falling at 2 m/s moves 2 mm per step",
        "end_time = 3.0     # s: the last grain enters at t = 2 s and lands by 2.2 s",
        'until = "rest"',
        "rest_duration = 0.2   # s: 200 steps, six times the time a grain takes to fall its own diameter",
        "",
        "[solver]",
        "tolerance = 1e-3   # relative residual, 10x the default: the default's sweeps would not fit 10 min of CPU",
        "",
        "[detection]",
        "alert_distance = 1.5e-3   # m: 30% of a radius, what a grain landing on the heap (< 1.5 m/s) moves in a step",
        "",
        "[gravity]",
        'type = "uniform"',
        "acceleration = [0.0, 0.0, -9.81]",
        "",
        "[output]",
        f'directory = "heap-{tag}-output"',
        "snapshot_interval = 0.1   # s",
        "",
        "[[materials]]",
        'name = "glass"',
        "density = 2500.0",
        "",
        "[[contact_laws]]",
        'materials = ["glass", "glass"]',
        "friction = 0.5",
        "restitution = 0.0",
        f"rolling_friction = {mu_r:g}",
        "twisting_friction = 0.0",
        "",
        "# A plane under the floor spheres catches any grain that would leave the floor's edge (none should:",
        "# measure.py counts grains beyond the floor).",
        "[[walls]]",
        'type = "plane"',
        f"point = [0.0, 0.0, {-FLOOR_RADIUS - FLOOR_JITTER - 0.0005:.4f}]",
        "normal = [0.0, 0.0, 1.0]",
        "",
        "[[inflow]]",
        f"count = {GRAINS}",
        "rate = 1000.0",
        f"radius_min = {RADIUS_MIN}",
        f"radius_max = {RADIUS_MAX}",
        "region_min = [-0.025, -0.025, 0.13]",
        "region_max = [0.025, 0.025, 0.20]",
        "velocity = [0.0, 0.0, -0.8]",
        "",
        f"# The rough floor: {len(floor)} fixed spheres (driven, held at rest).",
    ]
    for x, y, z in floor:
        lines.append(
            "[[bodies]]\n"
            'shape = "sphere"\n'
            f"radius = {FLOOR_RADIUS}\n"
            f"position = [{x:.6f}, {y:.6f}, {z:.6f}]\n"
            "driven = true"
        )
    return "\n".join(lines) + "\n"


def main():
    floor = floor_spheres()
    for mu_r in ROLLING:
        path = os.path.join(HERE, f"heap-mur{mu_r:g}.toml")
        with open(path, "w", encoding="utf-8") as f:
            f.write(scene_text(mu_r, floor))
        print(path, len(floor), "floor spheres")


if __name__ == "__main__":
    main()
