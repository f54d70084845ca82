#!/usr/bin/env bash
# When does the mean kinetic energy <E_c> of the accretion peak, and why? (docs/accretion-study.md,
# "The peak of <E_c>"). Runs the default 1 000-sphere cloud with grid cells of 10 m (the default),
# 11.5 m and 13 m to t = 3 000 s, and prints for each the initial packing fraction phi_0, the cloud's
# free-fall time, the measured peak time of <E_c> and the time at which a homologous free fall
# brings the cloud's mean packing fraction to jamming (phi_j = 0.55, 0.60, 0.64).
#
# Usage: examples/accretion/peak-vs-packing.sh [RUBBLE] [OUT_DIR]
#   RUBBLE default: build/release/apps/rubble; OUT_DIR default: peak-vs-packing-output.
#   About 50 s of CPU in all (one thread).
set -euo pipefail
rubble=${1:-build/release/apps/rubble}
out=${2:-peak-vs-packing-output}
cells=(10 11.5 13)
mkdir -p "$out"
"$rubble" run --print-default-scene > "$out/default.toml"
for cell in "${cells[@]}"; do
  # Run to a fixed end (the rest keys only go with until = "rest"), one snapshot every 10 min, and
  # the grid's cell size set (the generator's default is the largest diameter, 10 m).
  sed -e 's/^until = "rest".*/until = "end_time"/' -e '/^rest_speed/d' -e '/^rest_duration/d' \
    -e 's/^end_time = .*/end_time = 3000.0/' -e 's/^snapshot_interval = .*/snapshot_interval = 600.0/' \
    -e "s/^distribution = \"uniform_volume_fraction\".*/&\ncell_size = $cell/" "$out/default.toml" > "$out/cell-$cell.toml"
  grep -q "^cell_size = $cell$" "$out/cell-$cell.toml" || { echo "peak-vs-packing.sh: cannot set cell_size" >&2; exit 1; }
  echo "running cell size $cell m ..."
  OMP_NUM_THREADS=1 "$rubble" run "$out/cell-$cell.toml" --out "$out/cell-$cell" -q > "$out/cell-$cell.log"
done
python3 - "$out" "${cells[@]}" <<'EOF'
import sys, h5py, numpy as np
G = 6.674e-11
out, cells = sys.argv[1], sys.argv[2:]
print("cell (m) | phi_0 | t_ff of the cloud (min) | peak of <E_c> (min) | peak / t_ff | peak <E_c> (J) | "
      "homologous fall to phi_j = 0.55 / 0.60 / 0.64 (min)")
for cell in cells:
    with h5py.File(f"{out}/cell-{cell}/run.h5", "r") as f:
        t, kinetic = f["series/time"][:], f["series/kinetic_energy"][:]
        mass, volume = f["model/mass"][:], f["model/volume"][:]
    grains = mass > 0
    n = int(grains.sum())
    rho = mass[grains].sum() / volume[grains].sum()
    phi0 = volume[grains].sum() / (n * float(cell) ** 3)
    # Free fall of a uniform cloud of density rho phi_0: R/R0 = cos^2 b, t/t_ff = (b + sin b cos b) / (pi/2)
    # (the cycloid solution of a pressureless uniform sphere, e.g. Hunter 1962; t_ff = sqrt(3 pi / (32 G rho phi_0))).
    t_ff = np.sqrt(3 * np.pi / (32 * G * rho * phi0))
    def jam_time(phi_j):
        b = np.arccos(np.sqrt((phi0 / phi_j) ** (1 / 3)))
        return (b + np.sin(b) * np.cos(b)) / (np.pi / 2) * t_ff
    i = int(np.argmax(kinetic))
    jams = " / ".join(f"{jam_time(p) / 60:.1f}" for p in (0.55, 0.60, 0.64))
    print(f"{cell} | {phi0:.3f} | {t_ff / 60:.1f} | {t[i] / 60:.1f} | {t[i] / t_ff:.2f} | {kinetic[i] / n:.3g} | {jams}")
EOF
