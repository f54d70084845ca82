"""Writes the binary inputs of the CLI bad-input corpus (cases.txt) into OUTDIR.

usage: make_inputs.py OUTDIR [RUBBLE]

HDF5 files for `rubble gravity` (one mistake each, next to a valid one so that argument cases
are not masked by file errors), and run folders with unusable checkpoints for `rubble run
--resume`, FCLib problems for `rubble fclib`, and (given the RUBBLE binary) a run whose last
snapshot holds a NaN position for `rubble post`. Text inputs (scene and polyhedron files) live in tests/apps/inputs/ instead.
"""
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np


def gravity_file(path, positions=None, masses=None):
    with h5py.File(path, "w") as f:
        if positions is not None:
            f["positions"] = positions
        if masses is not None:
            f["masses"] = masses


def fclib_file(path, W, q, mu):
    """An FCLib local problem, W in triplet form (nz >= 0; FCLib's i = rows, p = columns)."""
    rows, columns = np.nonzero(W)
    with h5py.File(path, "w") as f:
        g = f.create_group("fclib_local")
        g["spacedim"] = np.array([3], dtype=np.int32)
        w = g.create_group("W")
        n = W.shape[0]
        w["m"] = np.array([n], dtype=np.int32)
        w["n"] = np.array([n], dtype=np.int32)
        w["nz"] = np.array([len(rows)], dtype=np.int32)
        w["nzmax"] = np.array([len(rows)], dtype=np.int32)
        w["i"] = rows.astype(np.int32)
        w["p"] = columns.astype(np.int32)
        w["x"] = W[rows, columns].astype(np.float64)
        v = g.create_group("vectors")
        v["q"] = np.asarray(q, dtype=np.float64)
        v["mu"] = np.asarray(mu, dtype=np.float64)


def uv_sphere_off(path, n_lat, n_lon, bump=None):
    """A convex UV sphere as OFF (planar quads, triangle fans at the poles), n_lat * n_lon + 2
    vertices; bump = (vertex, factor) moves one vertex radially."""
    t = np.pi * np.arange(1, n_lat + 1) / (n_lat + 1)
    p = 2 * np.pi * np.arange(n_lon) / n_lon
    tt, pp = np.meshgrid(t, p, indexing="ij")
    ring = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], axis=-1).reshape(-1, 3)
    v = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]])
    if bump is not None:
        v[bump[0]] *= bump[1]
    at = lambda i, j: 1 + (i - 1) * n_lon + (j % n_lon)
    last = len(v) - 1
    faces = [(0, at(1, j), at(1, j + 1)) for j in range(n_lon)]
    faces += [(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)) for i in range(1, n_lat) for j in range(n_lon)]
    faces += [(last, at(n_lat, j + 1), at(n_lat, j)) for j in range(n_lon)]
    with open(path, "w") as f:
        f.write(f"OFF\n{len(v)} {len(faces)} 0\n")
        f.writelines(f"{x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in v)
        f.writelines(f"{len(face)} {' '.join(map(str, face))}\n" for face in faces)


def nan_run(out, rubble, scene):
    """A real run (two spheres dropped, 0.01 s), copied and given a NaN position in its last snapshot."""
    work = f"{out}/nan_run_source"
    shutil.rmtree(work, ignore_errors=True)
    subprocess.run([rubble, "run", scene, "--out", work, "--end-time", "0.01", "-q"], check=True,
                   stdout=subprocess.DEVNULL)
    os.makedirs(f"{out}/nan_run", exist_ok=True)
    shutil.copy(f"{work}/run.h5", f"{out}/nan_run/run.h5")
    with h5py.File(f"{out}/nan_run/run.h5", "r+") as f:
        last = sorted(f["snapshots"].keys())[-1]
        position = f[f"snapshots/{last}/position"]
        x = position[...]
        x[1, 2] = np.nan
        position[...] = x


def flipped_run(out):
    """The real run of nan_run with one bit flipped inside a snapshot's position data: the
    dataset's Fletcher-32 checksum must catch it when the run file is read."""
    os.makedirs(f"{out}/flipped_run", exist_ok=True)
    shutil.copy(f"{out}/nan_run_source/run.h5", f"{out}/flipped_run/run.h5")
    with h5py.File(f"{out}/flipped_run/run.h5", "r") as f:
        offset = f["snapshots/000003/position"].id.get_chunk_info(0).byte_offset
    with open(f"{out}/flipped_run/run.h5", "r+b") as f:
        f.seek(offset + 5)
        byte = f.read(1)[0]
        f.seek(offset + 5)
        f.write(bytes([byte ^ 0x10]))


def main(out, rubble=None):
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


    # FCLib problems: a zero Delassus block on contact 1, an all-zero W, and a W_nn of 1e-300
    # with q_n = -1e300 (the normal impulse -q_n / W_nn overflows), and a good one.
    eye = np.eye(6)
    zero_block = eye.copy()
    zero_block[3:, 3:] = 0.0
    fclib_file(f"{out}/fclib_zero_block.hdf5", zero_block, [-1, 0, 0, -1, 0, 0], [0.3, 0.3])
    all_zero = np.zeros((6, 6))
    all_zero[0, 1] = 1e-3  # one entry, so that W is not empty, off the diagonal
    fclib_file(f"{out}/fclib_all_zero_diagonal.hdf5", all_zero, [-1, 0, 0, -1, 0, 0], [0.3, 0.3])
    tiny = np.eye(3) * 1e-300
    fclib_file(f"{out}/fclib_overflow.hdf5", tiny, [-1e300, 0, 0], [0.3])
    fclib_file(f"{out}/fclib_good.hdf5", eye, [-1, 0, 0, -2, 0, 0], [0.3, 0.3])

    # Gravity inputs whose field would overflow.
    huge = x.copy()
    huge[5, 2] = 1e200
    gravity_file(f"{out}/huge_position.h5", huge, m)
    heavy = m.copy()
    heavy[7] = 1e300
    gravity_file(f"{out}/huge_mass.h5", x, heavy)
    # A dataset whose shape asks for 10^12 x 3 doubles (24 TB) in a file of a few kB: chunked and
    # never written, so it costs no disk; it must be refused before any allocation.
    with h5py.File(f"{out}/huge_shape.h5", "w") as f:
        f.create_dataset("positions", shape=(10**12, 3), dtype="f8", chunks=(1024, 3))
        f.create_dataset("masses", shape=(10**12,), dtype="f8", chunks=(1024,))

    # A convex polyhedron of 10^5 vertices (checked on its hull in 2.4 s of CPU; it took 61 s
    # when every face was compared with every vertex), and a large one with a vertex pushed out.
    uv_sphere_off(f"{out}/sphere_1e5_vertices.off", 316, 316)
    uv_sphere_off(f"{out}/sphere_bumped.off", 40, 40, bump=(801, 1.02))

    # Files that are not regular or too large: a FIFO, links to /dev/zero (as a scene and as a
    # polyhedron file, the latter used by a scene), and a sparse scene file of 300 MiB (no disk used).
    for name in ("fifo.toml", "zero_link.toml", "zero_link.off", "big_scene.toml"):
        if os.path.lexists(f"{out}/{name}"):
            os.remove(f"{out}/{name}")
    os.mkfifo(f"{out}/fifo.toml")
    os.symlink("/dev/zero", f"{out}/zero_link.toml")
    os.symlink("/dev/zero", f"{out}/zero_link.off")
    with open(f"{out}/big_scene.toml", "wb") as f:
        f.truncate(300 << 20)
    with open(f"{out}/zero_mesh_scene.toml", "w") as f:
        f.write("[time]\ndt = 1e-4\nend_time = 0.01\n[[materials]]\nname = \"rock\"\ndensity = 2500.0\n"
                "[[contact_laws]]\nmaterials = [\"rock\", \"rock\"]\nfriction = 0.3\n"
                "[[bodies]]\nshape = \"polyhedron\"\nfile = \"zero_link.off\"\nposition = [0.0, 0.0, 0.0]\n")

    if rubble is not None:
        nan_run(out, rubble, os.path.join(os.path.dirname(os.path.abspath(__file__)), "inputs", "small_drop.toml"))
        flipped_run(out)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else None)
