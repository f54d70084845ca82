#!/usr/bin/env python3
"""The accretion study driven from Python: pack -> run to rest -> metrics table and plot.

    /usr/bin/python3 examples/python/accretion.py --n 125 --out accretion-125-py

Packs n = k^3 grains on the study's cubic grid (as `rubble pack cubic-grid`: diameters 7.5-10 m,
5164 kg/m^3, at rest, Barnes-Hut self-gravity), runs them until at rest while recording
OUT/run.h5 as `rubble run` does, prints the metrics of every tenth snapshot (time, kinetic
energy, Z, Z without rattlers, packing fraction nu, D_max), plots them into OUT/metrics.png and
leaves a checkpoint in OUT/checkpoints/ for friction_sweep.py. 125 spheres take about a second.
"""
import argparse
import pathlib

import rubble


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=125, help="grains, a cube k^3 (default 125)")
    parser.add_argument("--shape", default="spheres", choices=["spheres", "polyhedra", "mix"])
    parser.add_argument("--friction", type=float, default=0.0, help="Coulomb's mu (default 0, the study's)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", default=None, help="output folder (default accretion-N-SHAPE-py)")
    parser.add_argument("--no-plot", action="store_true", help="skip the PNG")
    args = parser.parse_args()
    out = pathlib.Path(args.out or f"accretion-{args.n}-{args.shape}-py")

    scene = rubble.pack("cubic-grid", n=args.n, shape=args.shape, dmin=7.5, dmax=10.0, density=5164.0,
                        friction=args.friction, seed=args.seed)
    print(f"{scene.name}: {scene.grain_count} grains, dt = {scene.dt:.4g} s, until at rest "
          f"(at most t = {scene.end_time:.0f} s)")
    sim = rubble.Simulation(scene)

    def progress(s):
        last = s.last_step
        print(f"  step {s.step_count:6d}  t = {s.time:8.1f} s  contacts {last['contacts']:5d}  "
              f"iterations {last['iterations']:4d}  Z = {s.metrics()['coordination']:.2f}")

    with sim:  # closes the run file at the end
        sim.record(out)
        summary = sim.run(until="rest", callback=progress, every=500)
    print(f"{'at rest' if summary['reached_rest'] else 'stopped'} at t = {summary['time']:.0f} s after "
          f"{summary['steps']} steps ({summary['wall_seconds']:.1f} s wall); run file {sim.record_path or out / 'run.h5'}")
    checkpoint = sim.save_checkpoint(out / "checkpoints")
    print(f"checkpoint for friction_sweep.py: {checkpoint}")

    metrics = rubble.post.metrics(out / "run.h5")
    columns = [("time", "t (s)", "{:9.0f}"), ("kinetic_energy", "E_k (J)", "{:10.3e}"),
               ("coordination", "Z", "{:6.2f}"), ("coordination_without_rattlers", "Z'", "{:6.2f}"),
               ("packing_fraction", "nu", "{:6.3f}"), ("inertia_packing_fraction", "nu_I", "{:6.3f}"),
               ("aggregate_diameter", "D_max (m)", "{:9.1f}")]
    print("  ".join(f"{title:>{len(fmt.format(0))}}" for _, title, fmt in columns))
    count = len(metrics["time"])
    for i in list(range(0, count, 10)) + ([count - 1] if (count - 1) % 10 else []):
        print("  ".join(fmt.format(metrics[name][i]) for name, _, fmt in columns))

    if not args.no_plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, 3, figsize=(12, 3.5))
        t = metrics["time"]
        axes[0].semilogy(t, metrics["kinetic_energy"])
        axes[0].set(xlabel="t (s)", ylabel="kinetic energy (J)")
        axes[1].plot(t, metrics["coordination"], label="Z")
        axes[1].plot(t, metrics["coordination_without_rattlers"], label="Z without rattlers")
        axes[1].set(xlabel="t (s)", ylabel="coordination")
        axes[1].legend()
        axes[2].plot(t, metrics["packing_fraction"], label="nu (D_max sphere)")
        axes[2].plot(t, metrics["inertia_packing_fraction"], label="nu_I (inertia ellipsoid)")
        axes[2].set(xlabel="t (s)", ylabel="packing fraction")
        axes[2].legend()
        fig.suptitle(f"{scene.name}: accretion from Python")
        fig.tight_layout()
        fig.savefig(out / "metrics.png", dpi=100)
        print(f"plot: {out / 'metrics.png'}")


if __name__ == "__main__":
    main()
