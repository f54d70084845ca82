"""Writes the binary inputs of the CLI bad-input corpus (cases.txt) into OUTDIR.

usage: make_inputs.py OUTDIR

HDF5 files for `rubble gravity` (one mistake each, next to a valid one so that argument cases
are not masked by file errors), and run folders with unusable checkpoints for `rubble run
--resume`. Text inputs (scene and polyhedron files) live in tests/apps/inputs/ instead.
"""
import os
import sys

import h5py
import numpy as np


def gravity_file(path, positions=None, masses=None):
    with h5py.File(path, "w") as f:
        if positions is not None:
            f["positions"] = positions
        if masses is not None:
            f["masses"] = masses


def main(out):
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, size=(20, 3))
    m = np.ones(20)
    gravity_file(f"{out}/good.h5", x, m)
    gravity_file(f"{out}/no_positions.h5", None, m)
    gravity_file(f"{out}/no_masses.h5", x, None)
    gravity_file(f"{out}/positions_n_by_2.h5", x[:, :2], m)
    gravity_file(f"{out}/masses_too_short.h5", x, m[:7])
    bad = x.copy()
    bad[4, 1] = np.nan
    gravity_file(f"{out}/nan_position.h5", bad, m)
    bad = x.copy()
    bad[2, 0] = np.inf
    gravity_file(f"{out}/infinite_position.h5", bad, m)
    bad = m.copy()
    bad[3] = -2.0
    gravity_file(f"{out}/negative_mass.h5", x, bad)
    with h5py.File(f"{out}/string_positions.h5", "w") as f:
        f["positions"] = np.array([b"a", b"b", b"c"])
        f["masses"] = m[:3]
    with h5py.File(f"{out}/positions_is_a_group.h5", "w") as f:
        f.create_group("positions")
        f["masses"] = m
    with open(f"{out}/not_hdf5.h5", "w") as f:
        f.write("positions = [[0, 0, 0]]\n")
    open(f"{out}/empty.h5", "w").close()
    with open(f"{out}/good.h5", "rb") as f:
        data = f.read()
    with open(f"{out}/truncated.h5", "wb") as f:
        f.write(data[: len(data) // 3])

    # A scene file of random bytes (NULs and invalid UTF-8 included).
    with open(f"{out}/garbage.toml", "wb") as f:
        f.write(bytes(rng.integers(0, 256, size=512, dtype=np.uint8)))

    # Run folders for --resume: none, garbage only, a truncated header only.
    os.makedirs(f"{out}/resume_empty", exist_ok=True)
    os.makedirs(f"{out}/resume_garbage/checkpoints", exist_ok=True)
    with open(f"{out}/resume_garbage/checkpoints/step-000000000100.ckpt", "wb") as f:
        f.write(b"RUBBLECK" + bytes(100))
    os.makedirs(f"{out}/resume_truncated/checkpoints", exist_ok=True)
    with open(f"{out}/resume_truncated/checkpoints/step-000000000100.ckpt", "wb") as f:
        f.write(b"RUBB")


if __name__ == "__main__":
    main(sys.argv[1])
