"""Chart of bench/gravity/every_k.sh: error of the held self-gravity field and gravity-stage time
against k. Usage: /usr/bin/python3 every_k.py every_k.csv out.png (prints the table too)."""
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import matplotlib.ticker
import numpy as np

data = np.genfromtxt(sys.argv[1], delimiter=",", names=True)
ks = sorted(set(int(k) for k in data["k"]))
rows = []
for k in ks:
    d = data[data["k"] == k]
    rows.append((k, d["max_rel_error"].max(), d["max_rel_error"].mean(), d["median_rel_error"].mean(),
                 d["gravity_seconds"].mean(), d["step_seconds"].mean()))
print("| k | max rel. error (all steps, all grains) | mean over steps of the max over grains | "
      "mean over steps of the median over grains | gravity stage ms/step | whole step ms/step | gravity speed-up |")
print("|---|---|---|---|---|---|---|")
base = rows[0][4]
for k, worst, median_max, median, g, s in rows:
    print(f"| {k} | {worst:.2e} | {median_max:.2e} | {median:.2e} | {1e3 * g:.3f} | {1e3 * s:.2f} | {base / g:.1f}x |")

fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
left.loglog([r[0] for r in rows[1:]], [r[1] for r in rows[1:]], "o-", label="max over steps and grains")
left.loglog([r[0] for r in rows[1:]], [r[2] for r in rows[1:]], "s-", label="mean over steps of max over grains")
left.loglog([r[0] for r in rows[1:]], [r[3] for r in rows[1:]], "^-", label="mean over steps of median over grains")
k1 = np.array([r[0] for r in rows[1:]], dtype=float)
left.loglog(k1, rows[1][2] * (k1 - 1) / (k1[0] - 1), "k:", label="∝ (k − 1): first order")
left.set_xlabel("k (self-gravity evaluated every k steps)")
left.set_ylabel("|a_used − a_exact| / |a_exact|")
left.set_xticks(ks[1:])
left.set_xticklabels([str(k) for k in ks[1:]])
left.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
left.legend(fontsize=8)
left.set_title("error of the held field")
right.plot(ks, [1e3 * r[4] for r in rows], "o-", label="gravity stage")
right.plot(ks, [1e3 * r[5] for r in rows], "s-", label="whole step")
right.set_xscale("log", base=2)
right.set_xticks(ks)
right.set_xticklabels([str(k) for k in ks])
right.set_xlabel("k")
right.set_ylabel("wall time per step (ms, 1 thread)")
right.legend()
right.set_title("time")
fig.suptitle("1000-sphere accretion, Barnes-Hut θ = 0.5, order 2")
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=110)
