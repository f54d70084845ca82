"""The module against the command line: same scene, same final state (bit for bit, by the state
hash `rubble run` prints), same run file, same packing text, same error messages."""
import glob
import os
import re

import h5py
import numpy as np
import pytest

import rubble
from conftest import cli_final_hash, run_cli


def test_run_to_end_time_gives_the_cli_state_bit_for_bit(rubble_exe, tiny_deposit, tmp_path):
    out = run_cli(rubble_exe, "run", tiny_deposit, "--out", tmp_path / "cli", "--end-time", 0.05, "-q")
    cli_step, cli_hash = cli_final_hash(out.stdout)

    scene = rubble.load_scene(tiny_deposit)
    scene.end_time = 0.05
    sim = rubble.Simulation(scene)
    summary = sim.run()
    assert summary["step"] == cli_step == 500
    assert sim.state_hash() == cli_hash


def test_a_python_loop_of_steps_gives_the_same_state_as_run(tiny_deposit):
    a = rubble.Simulation(rubble.load_scene(tiny_deposit))
    for _ in range(300):
        a.step()
    b = rubble.Simulation(rubble.load_scene(tiny_deposit))
    b.run(until=0.03)
    assert a.step_count == b.step_count == 300
    assert a.state_hash() == b.state_hash()
    np.testing.assert_array_equal(a.positions, b.positions)


def test_until_rest_stops_on_the_cli_step(rubble_exe, source_dir, tmp_path):
    # The built-in accretion shrunk to 27 spheres, run until at rest as `rubble run` does.
    text = rubble.default_scene().text
    text = re.sub(r"cells_per_side = \d+", "cells_per_side = 3", text)
    path = tmp_path / "small-accretion.toml"
    path.write_text(text)
    out = run_cli(rubble_exe, "run", path, "--out", tmp_path / "cli", "-q")
    assert "at rest" in out.stdout or "done" in out.stdout
    cli_step, cli_hash = cli_final_hash(out.stdout)

    sim = rubble.Simulation(rubble.load_scene(path))
    summary = sim.run()  # until=None: the scene's own stop rule
    assert summary["step"] == cli_step
    assert sim.state_hash() == cli_hash


def test_recorded_run_file_matches_the_cli_run_file(rubble_exe, tiny_deposit, tmp_path):
    run_cli(rubble_exe, "run", tiny_deposit, "--out", tmp_path / "cli", "--end-time", 0.05, "-q")
    scene = rubble.load_scene(tiny_deposit)
    scene.end_time = 0.05
    sim = rubble.Simulation(scene)
    sim.record(tmp_path / "py")
    sim.run()
    sim.close()
    with h5py.File(tmp_path / "cli" / "run.h5") as cli, h5py.File(tmp_path / "py" / "run.h5") as py:
        assert cli["scene"][()] == py["scene"][()]
        # Both say why they ended and store the settings as used, with units.
        assert cli["run"].attrs["status"] == py["run"].attrs["status"] == "end_time"
        assert cli["run"].attrs["stop_reason"].startswith("end time reached at t = ")
        assert py["run"].attrs["stop_reason"].startswith("end time reached at t = ")
        for name in ("time_step", "alert_distance", "pair_list_margin", "snapshot_every_steps"):
            assert cli["run"][name][()] == py["run"][name][()], name
            assert cli["run"][name].attrs["units"] == py["run"][name].attrs["units"], name
        for column in ("step", "time", "kinetic_energy", "contacts", "active_contacts", "iterations", "residual",
                       "potential_energy", "total_energy", "linear_momentum_z", "angular_momentum_x"):
            np.testing.assert_array_equal(cli["series"][column][:], py["series"][column][:])
        assert sorted(cli["snapshots"].keys()) == sorted(py["snapshots"].keys())
        last = sorted(cli["snapshots"].keys())[-1]
        for dataset in ("position", "orientation", "velocity", "angular_velocity"):
            np.testing.assert_array_equal(cli["snapshots"][last][dataset][:], py["snapshots"][last][dataset][:])


def test_orientations_are_x_y_z_w_and_the_run_file_w_x_y_z(tiny_deposit, tmp_path):
    sim = rubble.Simulation(rubble.load_scene(tiny_deposit))
    sim.angular_velocities[:27] = [3.0, -2.0, 1.0]  # spin the grains (rad/s) through the view
    sim.record(tmp_path / "run", end_time=0.03)
    sim.run(until=0.03)
    sim.close()
    q = sim.orientations.copy()
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    assert np.max(np.abs(q[:, :3])) > 1e-4  # the grains did turn: the test can tell the orders apart
    with h5py.File(tmp_path / "run" / "run.h5") as f:
        last = sorted(f["snapshots"].keys())[-1]
        wxyz = f["snapshots"][last]["orientation"][:]
    np.testing.assert_array_equal(rubble.quaternion.xyzw_to_wxyz(q), wxyz)
    np.testing.assert_array_equal(rubble.quaternion.wxyz_to_xyzw(wxyz), q)
    reader = rubble.RunReader(tmp_path / "run" / "run.h5")
    np.testing.assert_array_equal(reader.snapshot(-1)["orientations"], q)


def test_checkpoint_round_trip_is_bit_for_bit(tiny_deposit, tmp_path):
    reference = rubble.Simulation(rubble.load_scene(tiny_deposit))
    reference.run(until=0.04)

    sim = rubble.Simulation(rubble.load_scene(tiny_deposit))
    sim.run(until=0.02)
    path = sim.save_checkpoint(tmp_path / "ckpt")
    assert os.path.basename(path) == "step-000000000200.ckpt"
    resumed = rubble.Simulation.from_checkpoint(path)
    assert resumed.step_count == 200
    resumed.run(until=0.04)
    assert resumed.state_hash() == reference.state_hash()
    # A folder works too (the newest valid checkpoint).
    assert rubble.Simulation.from_checkpoint(tmp_path / "ckpt").state_hash() == sim.state_hash()


def test_a_cli_checkpoint_goes_on_in_python_to_the_cli_state(rubble_exe, tiny_deposit, tmp_path):
    out = run_cli(rubble_exe, "run", tiny_deposit, "--out", tmp_path / "full", "--end-time", 0.04, "-q")
    _, full_hash = cli_final_hash(out.stdout)
    run_cli(rubble_exe, "run", tiny_deposit, "--out", tmp_path / "half", "--end-time", 0.02, "-q")
    sim = rubble.Simulation.from_checkpoint(tmp_path / "half")  # a run folder: its checkpoints/
    assert sim.step_count == 200
    sim.run(until=0.04)
    assert sim.state_hash() == full_hash


def test_a_damaged_checkpoint_raises_checkpoint_error(tiny_deposit, tmp_path):
    sim = rubble.Simulation(rubble.load_scene(tiny_deposit))
    sim.step(3)
    path = sim.save_checkpoint(tmp_path)
    data = bytearray(open(path, "rb").read())
    data[len(data) // 2] ^= 0xFF
    open(path, "wb").write(bytes(data))
    with pytest.raises(rubble.CheckpointError, match="CRC|checksum"):
        rubble.Simulation.from_checkpoint(path)


@pytest.mark.parametrize("args", [
    dict(kind="cubic-grid", n=27, shape="spheres", seed=4),
    dict(kind="cloud", n=50, shape="mix", polyhedron_fraction=0.3, dmin=2, dmax=3, friction=0.5, seed=2),
    dict(kind="box", n=20, shape="polyhedra", distribution="bins", bins=[(8, 0.5), (10, 0.5)], g=3.0),
])
def test_pack_writes_the_cli_text(rubble_exe, args):
    cli_args = ["pack", args["kind"]]
    names = {"n": "--n", "shape": "--shape", "seed": "--seed", "polyhedron_fraction": "--polyhedron-fraction",
             "dmin": "--dmin", "dmax": "--dmax", "friction": "--friction", "distribution": "--distribution",
             "bins": "--bins", "g": "--g"}
    for key, value in args.items():
        if key == "kind":
            continue
        if key == "bins":
            value = ",".join(f"{d}:{f}" for d, f in value)
        cli_args += [names[key], value]
    cli_text = run_cli(rubble_exe, *cli_args).stdout
    scene = rubble.pack(**args)
    # The header line spells the numbers of the bins as given; everything below it is the same.
    assert scene.text.split("\n", 2)[2] == cli_text.split("\n", 2)[2]
    assert scene.body_count == rubble.parse_scene(cli_text).body_count


def test_pack_rejects_bad_options_like_the_cli():
    with pytest.raises(ValueError, match="--shape: expected one of spheres, polyhedra, mix"):
        rubble.pack(shape="cubes")
    with pytest.raises(ValueError, match="not a cube"):
        rubble.pack(n=10)


def test_scene_errors_carry_the_cli_message(rubble_exe, source_dir):
    bad = sorted(glob.glob(str(source_dir / "tests" / "scene" / "bad" / "*.toml")))
    assert len(bad) > 10
    for path in bad[:12]:
        out = run_cli(rubble_exe, "run", path, "--out", os.devnull, "-q", check=False)
        assert out.returncode == 2, path
        with pytest.raises(rubble.SceneError) as error:
            rubble.load_scene(path)
        assert f"rubble run: error: {error.value}" in out.stderr, path
        header = open(path).read()
        line = re.search(r"# line: (\d+)", header)
        if line:
            assert error.value.line == int(line.group(1)), path
        assert error.value.file == path
        assert str(error.value).endswith(error.value.message)


def test_held_self_gravity_run_file_matches_the_cli(rubble_exe, tmp_path):
    # Self-gravity evaluated every 3 steps: the run file's potential energy on the held steps is
    # the last value minus the held forces' work, as `rubble run` writes it.
    text = rubble.default_scene().text
    text = re.sub(r"cells_per_side = \d+", "cells_per_side = 3", text)
    text = text.replace('[gravity]\ntype = "tree"', '[gravity]\ntype = "tree"\nevaluate_every = 3')
    assert "evaluate_every = 3" in text
    path = tmp_path / "held.toml"
    path.write_text(text)
    out = run_cli(rubble_exe, "run", path, "--out", tmp_path / "cli", "--end-time", 100 * rubble.load_scene(path).dt,
                  "-q")
    _, cli_hash = cli_final_hash(out.stdout)
    sim = rubble.Simulation(rubble.load_scene(path))
    sim.record(tmp_path / "py", end_time=100 * sim.dt)
    sim.run(until=100 * sim.dt)
    sim.close()
    assert sim.state_hash() == cli_hash
    with h5py.File(tmp_path / "cli" / "run.h5") as cli, h5py.File(tmp_path / "py" / "run.h5") as py:
        np.testing.assert_array_equal(cli["series"]["potential_energy"][:], py["series"]["potential_energy"][:])
