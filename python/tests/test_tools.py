"""rubble.gravity, rubble.fclib, rubble.post, random polyhedra and scenes built from dicts,
against analytical or independent references."""
import os

import h5py
import numpy as np
import pytest

import rubble


def test_gravity_of_two_masses_is_newtons_law():
    x = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]])
    m = np.array([2.0, 5.0])
    G = 1.0
    # The kernels refine an approximate 1/sqrt(r^2) by Newton steps: within 1.7e-8 of exact
    # (gravity/README.md); 2e-8 relative here.
    tol = 2e-8
    for method in ("direct", "tree"):
        a, phi = rubble.gravity.field(x, m, method=method, G=G, potential=True)
        np.testing.assert_allclose(a[0], G * 5.0 / 25.0 * np.array([0.6, 0.8, 0.0]), rtol=tol, atol=1e-20)
        np.testing.assert_allclose(a[1], -G * 2.0 / 25.0 * np.array([0.6, 0.8, 0.0]), rtol=tol, atol=1e-20)
        np.testing.assert_allclose(phi, [-G * 5.0 / 5.0, -G * 2.0 / 5.0], rtol=tol)
    # Plummer softening: 1 / (r^2 + eps^2)^(3/2)
    a = rubble.gravity.field(x, m, method="direct", G=G, softening=1.0)
    np.testing.assert_allclose(np.linalg.norm(a[0]), 5.0 * 5.0 / 26.0 ** 1.5, rtol=tol)


def test_tree_agrees_with_the_direct_sum():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(2000, 3))
    m = rng.uniform(1.0, 2.0, size=2000)
    direct = rubble.gravity.field(x, m, method="direct")
    tree, timings = rubble.gravity.field(x, m, method="tree", theta=0.5, order=2, timings=True)
    error = np.linalg.norm(tree - direct, axis=1) / np.linalg.norm(direct, axis=1)
    assert np.median(error) < 1e-3 and timings["walk_seconds"] >= 0.0
    # The float kernels: each grain's field within 1e-5 of the double tree's (gravity/README.md).
    single = rubble.gravity.field(x, m, method="tree", theta=0.5, order=2, precision="single")
    assert np.max(np.linalg.norm(single - tree, axis=1) / np.linalg.norm(tree, axis=1)) < 1e-5
    assert not np.array_equal(single, tree)
    with pytest.raises(ValueError, match="precision"):
        rubble.gravity.field(x, m, precision="half")
    with pytest.raises(ValueError, match="theta"):
        rubble.gravity.field(x, m, theta=-1.0)
    with pytest.raises(ValueError, match="masses"):
        rubble.gravity.field(x, m[:10])
    with pytest.raises(ValueError, match="backend"):
        rubble.gravity.field(x, m, backend="opencl")
    # The GPU tree computes in double only: single precision there is refused on every machine.
    with pytest.raises(ValueError, match="double precision only"):
        rubble.gravity.field(x, m, backend="cuda", precision="single")


def test_gravity_on_the_gpu_or_the_reason_why_not():
    rng = np.random.default_rng(5)
    x = rng.normal(size=(3000, 3))
    m = rng.uniform(1.0, 2.0, size=3000)
    try:
        gpu, timings = rubble.gravity.field(x, m, method="tree", backend="cuda", timings=True)
    except ValueError as error:  # no GPU, driver or CUDA build here: said, not silently run on the CPU
        assert "cuda" in str(error)
        return
    cpu = rubble.gravity.field(x, m, method="tree")
    # Same tree, same accepted nodes: rounding differences only (gravity/README.md, "CUDA backend").
    assert np.max(np.linalg.norm(gpu - cpu, axis=1) / np.linalg.norm(cpu, axis=1)) < 1e-6
    assert timings["transfer_seconds"] >= 0.0


def test_fclib_single_contact_is_solved_exactly():
    # W = diag(2, 1, 1), q = (-1, 0.5, 0), mu = 0.1: u_n = 0 needs r_n = 0.5; the tangential
    # trial 0.5 exceeds mu r_n = 0.05, so the contact slides with r_t = -0.05 (opposing u_t).
    W = np.diag([2.0, 1.0, 1.0])
    q = np.array([-1.0, 0.5, 0.0])
    for w in (W, __import__("scipy.sparse", fromlist=["csr_matrix"]).csr_matrix(W)):
        sol = rubble.fclib.solve((w, q, [0.1]), tolerance=1e-12)
        assert sol["converged"]
        np.testing.assert_allclose(sol["r"], [0.5, -0.05, 0.0], atol=1e-12)
        np.testing.assert_allclose(sol["u"], W @ sol["r"] + q, atol=1e-12)
        assert sol["u"][0] == pytest.approx(0.0, abs=1e-12)


def test_fclib_point_residual_sums_to_the_fclib_error_on_a_unit_diagonal():
    # W scaled to a unit diagonal: each point's natural map in velocity units (rho = W_nn = 1) is
    # the FCLib map, so ||point_residual|| / ||q|| is the FCLib error of the same iterate.
    rng = np.random.default_rng(3)
    nc = 6
    A = rng.normal(size=(3 * nc, 3 * nc))
    W = A @ A.T + 0.5 * np.eye(3 * nc)
    d = 1.0 / np.sqrt(np.diag(W))
    W = W * d[:, None] * d[None, :]
    q = rng.normal(size=3 * nc)
    q[0::3] -= 1.0
    mu = np.full(nc, 0.4)
    one_sweep = rubble.fclib.solve((W, q, mu), tolerance=1e-300, max_iterations=1, polish="none")
    assert len(one_sweep["point_residual"]) == nc
    assert one_sweep["error"] > 1e-6
    assert np.linalg.norm(one_sweep["point_residual"]) / np.linalg.norm(q) == pytest.approx(one_sweep["error"],
                                                                                          rel=1e-12)
    solved = rubble.fclib.solve((W, q, mu), tolerance=1e-12)
    assert solved["converged"] and max(solved["point_residual"]) < 1e-10


def test_fclib_file_round_trip(tmp_path):
    # An FCLib file written with h5py (layout: nlgs_solver/fclib_file.hpp), W stored as triplets.
    rng = np.random.default_rng(1)
    nc = 4
    A = rng.normal(size=(3 * nc, 3 * nc))
    W = A @ A.T + 3 * nc * np.eye(3 * nc)
    q = rng.normal(size=3 * nc)
    mu = np.full(nc, 0.3)
    rows, cols = np.nonzero(W)
    path = tmp_path / "problem.hdf5"
    with h5py.File(path, "w") as f:
        g = f.create_group("fclib_local/W")
        g["m"], g["n"], g["nz"], g["nzmax"] = [3 * nc], [3 * nc], [len(rows)], [len(rows)]
        g["i"], g["p"], g["x"] = rows.astype(np.int32), cols.astype(np.int32), W[rows, cols]
        f["fclib_local/vectors/q"], f["fclib_local/vectors/mu"] = q, mu
        f["fclib_local/spacedim"] = [3]
    W_read, q_read, mu_read = rubble.fclib.read(path)
    np.testing.assert_allclose(W_read.toarray(), W)
    from_file = rubble.fclib.solve(path, tolerance=1e-10)
    from_arrays = rubble.fclib.solve((W, q, mu), tolerance=1e-10)
    assert from_file["converged"] and from_file["error"] <= 1e-10
    np.testing.assert_allclose(from_file["r"], from_arrays["r"], atol=1e-12)
    with pytest.raises(rubble.FclibFileError):
        rubble.fclib.solve(tmp_path / "missing.hdf5")


def polyhedron_volume(vertices, faces):
    """Volume by the divergence theorem over fan triangles of the faces (independent of CGAL)."""
    total = 0.0
    for face in faces:
        p0 = vertices[face[0]]
        for k in range(1, len(face) - 1):
            total += np.dot(p0, np.cross(vertices[face[k]], vertices[face[k + 1]])) / 6.0
    return total


def test_random_polyhedron_is_seeded_and_closed():
    # merge_angle_degrees=0 keeps the hull's triangles: exactly planar faces, so the fan volume
    # below is exact up to round-off (merged faces are planar only to within the merge angle).
    a = rubble.random_polyhedron(7, diameter=2.0, merge_angle_degrees=0.0)
    b = rubble.random_polyhedron(7, diameter=2.0, merge_angle_degrees=0.0)
    c = rubble.random_polyhedron(8, diameter=2.0, merge_angle_degrees=0.0)
    np.testing.assert_array_equal(a["vertices"], b["vertices"])
    assert a["vertices"].shape != c["vertices"].shape or not np.array_equal(a["vertices"], c["vertices"])
    assert polyhedron_volume(a["vertices"], a["faces"]) == pytest.approx(a["volume"], rel=1e-10)
    # Inside the circumscribed sphere of diameter 2: no two vertices farther apart than 2; the
    # bounding radius is about the centroid (the body origin), so at least 1.
    v = a["vertices"]
    assert np.max(np.linalg.norm(v[:, None, :] - v[None, :, :], axis=2)) <= 2.0 + 1e-12
    assert a["bounding_radius"] == pytest.approx(np.max(np.linalg.norm(v, axis=1)), rel=1e-14)


def test_scene_from_dict_and_write_back(tmp_path):
    scene = rubble.scene_from_dict({
        "name": "two", "seed": 2,
        "time": {"dt": 1e-4, "end_time": 0.01},
        "gravity": {"type": "none"},
        "materials": [{"name": "rock", "density": 3000.0}],
        "default_contact_law": {"friction": 0.5},
        "bodies": [{"shape": "sphere", "radius": 0.5, "position": np.array([0.0, 0.0, 0.0])},
                   {"shape": "sphere", "radius": 0.25, "position": [2.0, 0.0, 0.0], "velocity": [-1.0, 0, 0]}],
    })
    assert scene.body_count == 2 and scene.materials == ["rock"]
    np.testing.assert_allclose(scene.masses, 3000.0 * 4.0 / 3.0 * np.pi * np.array([0.5, 0.25]) ** 3, rtol=1e-14)
    path = tmp_path / "two.toml"
    scene.write(path, explicit=True)
    again = rubble.load_scene(path)
    np.testing.assert_array_equal(again.positions, scene.positions)
    np.testing.assert_array_equal(again.velocities, scene.velocities)
    with pytest.raises(rubble.SceneError) as error:
        rubble.scene_from_dict({"time": {"dt": 1e-4, "end_time": 1.0, "speed": 3}})
    assert error.value.key == "time.speed" and error.value.line == 4


def test_polyhedra_of_a_scene_come_as_vertices_and_faces():
    scene = rubble.pack("cloud", n=5, shape="polyhedra", dmin=2, dmax=3, seed=3)
    assert scene.shapes == ["polyhedron"] * 5
    p = scene.polyhedron(0)
    assert p["vertices"].shape[1] == 3 and all(f.dtype.kind == "i" for f in p["faces"])
    # Faces merged within 1 degree are not exactly planar: the fan volume differs by ~1e-4.
    assert polyhedron_volume(p["vertices"], p["faces"]) == pytest.approx(scene.volumes[0], rel=1e-3)


def test_metrics_of_a_run_file_equal_the_live_ones(tmp_path, tiny_deposit):
    sim = rubble.Simulation(rubble.load_scene(tiny_deposit))
    with sim:
        sim.record(tmp_path / "run", end_time=0.05)
        sim.run(until=0.05)
    live = rubble.post.metrics(sim)
    table = rubble.post.metrics(tmp_path / "run" / "run.h5")
    reader = rubble.post.read_run(tmp_path / "run" / "run.h5")
    # snapshot_interval = 0.02 s: steps 0, 200, 400 and the last one, 500
    assert len(table["time"]) == reader.snapshot_count == 4
    for name in ("kinetic_energy", "potential_energy", "coordination", "packing_fraction", "aggregate_diameter",
                 "contact_points", "rattlers"):
        assert table[name][-1] == pytest.approx(live[name], rel=1e-12, abs=1e-300), name
    series = reader.series()
    assert len(series["step"]) == 500 and set(series["stage_seconds"]) == set(rubble.STAGES)


def test_vtk_series_and_post_process(tmp_path, tiny_deposit):
    sim = rubble.Simulation(rubble.load_scene(tiny_deposit))
    series = rubble.VtkSeries(tmp_path / "vtk", sim)
    for _ in range(3):
        sim.step(10)
        series.write(sim)
    assert series.snapshot_count == 3
    names = sorted(p.split("/")[-1] for p in series.collections)
    assert "spheres.pvd" in names and "contacts.pvd" in names
    sim.record(tmp_path / "run", end_time=0.01)
    sim.step(20)
    sim.close()
    files = rubble.post.process(tmp_path / "run" / "run.h5", tmp_path / "post", plots=False)
    assert any(f.endswith(".csv") for f in files)
    with h5py.File(tmp_path / "run" / "run.h5") as f:
        assert f["run"].attrs["status"] == "closed"  # closed at t = 5 ms, before its end time (10 ms)
        assert f["run"].attrs["stop_reason"] == "closed by the script at t = 0.005 s (step 50)"


def test_recording_with_vtk_true_writes_the_paraview_series(tmp_path, tiny_deposit):
    # [output] vtk = true is not ignored by a Python recording: one ParaView entry per snapshot.
    text = open(tiny_deposit, encoding="utf-8").read().replace("[output]\n", "[output]\nvtk = true\n", 1)
    scene_path = tmp_path / "vtk.toml"
    scene_path.write_text(text)
    sim = rubble.Simulation(rubble.load_scene(scene_path))
    sim.record(tmp_path / "run", end_time=0.1)  # snapshot_interval 0.02 s: t = 0, 0.02, ..., 0.1
    sim.run(until=0.1)
    sim.close()
    with h5py.File(tmp_path / "run" / "run.h5") as f:
        snapshots = len(f["snapshots"])
    pvd = (tmp_path / "run" / "vtk" / "spheres.pvd").read_text()
    assert snapshots == 6 and pvd.count("<DataSet ") == snapshots


def test_post_process_plots_with_this_interpreter_or_warns(tmp_path, tiny_deposit, capfd):
    sim = rubble.Simulation(rubble.load_scene(tiny_deposit))
    sim.record(tmp_path / "run", end_time=0.01)
    sim.step(20)
    sim.close()
    pytest.importorskip("matplotlib")
    # The running interpreter (it has matplotlib) and the package's plots.py; a deposit's figures.
    files = [os.path.basename(f) for f in rubble.post.process(tmp_path / "run" / "run.h5", tmp_path / "post")]
    assert "kinetic_energy.png" in files and "impulse_distribution.png" in files
    assert "aggregate_diameter.png" not in files  # uniform gravity: a deposit, not an aggregate
    # An interpreter that cannot plot: the other files, and a warning instead of an error.
    files = rubble.post.process(tmp_path / "run" / "run.h5", tmp_path / "post2", python=str(tmp_path / "no-python"))
    assert not any(f.endswith(".png") for f in files) and any(f.endswith("metrics.csv") for f in files)
    assert "plots not drawn" in capfd.readouterr().err


def test_scene_from_dict_with_generators_and_contact_laws():
    scene = rubble.scene_from_dict({
        "name": "grid", "seed": 4,
        "time": {"dt": "auto", "end_time": 100.0},
        "gravity": {"type": "direct"},
        "materials": [{"name": "rock", "density": 3000.0}, {"name": "ice", "density": 900.0}],
        "contact_laws": [{"materials": ["rock", "rock"], "friction": 0.6, "restitution": 0.1},
                         {"materials": ["rock", "ice"], "friction": 0.2},
                         {"materials": ["ice", "ice"], "friction": 0.05}],
        "generators": [{"type": "cubic_grid", "cells_per_side": 3, "cell_size": 2.0, "radius_min": 0.5,
                        "radius_max": 0.8, "material": "ice"}],
    })
    assert scene.grain_count == 27 and scene.gravity == "self"
    assert set(scene.material_ids) == {1}
    sim = rubble.Simulation(scene)
    law = sim.contact_law("rock", "rock")
    assert (law["friction"], law["restitution"], law["cohesion"], law["rolling_friction"]) == (0.6, 0.1, 0.0, 0.0)
    assert sim.contact_law("ice", "rock")["friction"] == 0.2
    assert sim.contact_law(1, 1)["friction"] == 0.05
    sim.set_contact_law("rock", "rock", cohesion=2.5, rolling_friction=0.05)
    law = sim.contact_law("rock", "rock")
    assert (law["friction"], law["cohesion"], law["rolling_friction"], law["twisting_friction"]) == (0.6, 2.5, 0.05, 0.0)
    with pytest.raises(ValueError, match="cohesion"):
        sim.set_contact_law("rock", "rock", cohesion=-1.0)


def test_rolling_and_twisting_friction_are_refused_for_polyhedra():
    # As the scene file: these laws act on sphere contacts only (nlgs_solver/README.md, "Polyhedra").
    sim = rubble.Simulation(rubble.pack("cloud", n=5, shape="polyhedra", dmin=2, dmax=3, seed=3))
    for key in ("rolling_friction", "twisting_friction"):
        with pytest.raises(ValueError, match="used by polyhedron grains"):
            sim.set_contact_law(0, 0, **{key: 0.05})
    assert sim.contact_law(0, 0)["rolling_friction"] == 0.0
    sim.set_contact_law(0, 0, friction=0.4)  # the rest of the law may change
    assert sim.contact_law(0, 0)["friction"] == 0.4
