"""rubble.Simulation against analytical references: free flight, a sphere resting on a plane
(contact frame, gap, impulse m g h), Coulomb sliding (deceleration mu g) with the friction
changed between steps, fixed bodies; numpy views without copies; Ctrl-C and the GIL."""
import os
import signal
import threading
import time

import numpy as np
import pytest

import rubble

G0 = 9.81


def one_sphere(friction=0.5, gravity=True, z=0.01, radius=0.01, dt=1e-4, end_time=1.0):
    """A glass sphere of radius 1 cm on (or above) a plane floor z = 0."""
    scene = {
        "name": "one-sphere",
        "time": {"dt": dt, "end_time": end_time},
        "solver": {"tolerance": 1e-10, "penetration_correction": 0.0},
        "gravity": {"type": "uniform", "acceleration": [0.0, 0.0, -G0]} if gravity else {"type": "none"},
        "materials": [{"name": "glass", "density": 2500.0}],
        "default_contact_law": {"friction": friction, "restitution": 0.0},
        "walls": [{"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}],
        "bodies": [{"shape": "sphere", "radius": radius, "position": [0.0, 0.0, z]}],
    }
    return rubble.scene_from_dict(scene)


def test_state_arrays_are_views_without_copies():
    sim = rubble.Simulation(one_sphere())
    for name in ("positions", "velocities", "angular_velocities", "orientations"):
        a, b = getattr(sim, name), getattr(sim, name)
        assert not a.flags["OWNDATA"] and np.shares_memory(a, b), name
        assert a.base is not None
    assert sim.positions.shape == (2, 3) and sim.orientations.shape == (2, 4)
    np.testing.assert_array_equal(sim.orientations[0], [0.0, 0.0, 0.0, 1.0])  # identity, (x, y, z, w)
    view = sim.positions
    before = sim.state_hash()
    view[0, 2] = 0.5  # writing into the view changes the simulation's state
    assert sim.positions[0, 2] == 0.5 and sim.state_hash() != before
    del sim  # the view keeps the simulation alive
    assert view[0, 2] == 0.5


def test_free_flight_with_a_velocity_set_and_dt_changed_between_steps():
    sim = rubble.Simulation(one_sphere(gravity=False, z=1.0))
    v = np.array([0.3, -0.2, 0.1])
    sim.velocities = np.array([v, [0.0, 0.0, 0.0]])
    sim.step(10)  # 10 steps of 1e-4 s
    sim.dt = 5e-4
    sim.step(4)  # 4 steps of 5e-4 s
    t = 10 * 1e-4 + 4 * 5e-4
    assert sim.time == pytest.approx(t, rel=1e-13)
    np.testing.assert_allclose(sim.positions[0], np.array([0.0, 0.0, 1.0]) + v * t, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(sim.positions[1], [0.0, 0.0, 0.0])  # the wall


def test_sphere_resting_on_a_plane_carries_its_weight():
    sim = rubble.Simulation(one_sphere())
    sim.step(200)
    c = sim.contacts()
    assert len(c["gap"]) == 1
    mass = sim.masses[0]
    h = sim.dt
    # The normal points from body a to body b: from the floor (a) up to the grain (b), or the
    # reverse; the impulse on b along n is the weight's impulse over one step.
    a, b = int(c["body_a"][0]), int(c["body_b"][0])
    assert {a, b} == {0, 1}
    up = np.array([0.0, 0.0, 1.0]) if b == 0 else np.array([0.0, 0.0, -1.0])
    np.testing.assert_allclose(c["normal"][0], up, atol=1e-12)
    np.testing.assert_allclose(c["frame"][0][0], c["normal"][0])  # rows of the frame: n, t, s
    np.testing.assert_allclose(c["frame"][0] @ c["frame"][0].T, np.eye(3), atol=1e-12)
    assert abs(c["gap"][0]) < 1e-6
    assert c["impulse"][0][0] == pytest.approx(mass * G0 * h, rel=1e-6)
    np.testing.assert_allclose(c["impulse_world"][0], c["impulse"][0][0] * up, rtol=0, atol=1e-12 * mass)
    assert rubble.CONTACT_STATUS[int(c["status"][0])] == "sticking"
    assert abs(sim.velocities[0, 2]) < 1e-9


def test_rolling_sphere_carries_the_rolling_resistance_bound_in_its_angular_impulse():
    # A sphere rolling on the floor with rolling friction mu_r: the resisting torque is at its bound
    # mu_r r f_n (docs/scene-file.md), so over a step the contact's angular impulse has the norm
    # mu_r r m g h, about an axis in the tangent plane (no twisting), against the rolling.
    mu_r, radius, v0 = 0.1, 0.01, 0.05
    sim = rubble.Simulation(one_sphere(radius=radius))
    sim.set_contact_law("glass", "glass", rolling_friction=mu_r)
    sim.step(50)  # settle onto the floor
    sim.velocities = np.array([[v0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    sim.angular_velocities = np.array([[0.0, v0 / radius, 0.0], [0.0, 0.0, 0.0]])  # rolling in +x
    sim.step(20)
    c = sim.contacts()
    m = c["angular_impulse"][0]  # on body b, in the frame (n, t, s)
    bound = mu_r * radius * sim.masses[0] * G0 * sim.dt
    assert np.linalg.norm(m) == pytest.approx(bound, rel=1e-6)
    assert abs(m[0]) < 1e-9 * bound  # no twisting
    on_sphere = (m if int(c["body_b"][0]) == 0 else -m) @ c["frame"][0]  # world vector on the sphere
    assert on_sphere[1] < -0.999 * bound  # against the spin about +y


def test_coulomb_sliding_decelerates_at_mu_g_and_friction_can_change_between_steps():
    mu, v0 = 0.4, 1.0
    sim = rubble.Simulation(one_sphere(friction=mu))
    sim.step(50)  # settle onto the floor
    sim.velocities = np.array([[v0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    sim.angular_velocities = np.zeros((2, 3))
    # A sliding ball also spins up; while it slides, the contact force is mu m g backwards, so
    # the centre decelerates at mu g (it rolls once v = 5/7 v0: after 2 v0 / (7 mu g) = 0.073 s).
    n = 300  # 0.03 s: still sliding
    sim.step(n)
    assert sim.velocities[0, 0] == pytest.approx(v0 - mu * G0 * n * sim.dt, rel=1e-6)
    assert rubble.CONTACT_STATUS[int(sim.contacts()["status"][0])] == "sliding"
    assert sim.contact_law("glass", "glass") == {"friction": mu, "restitution": 0.0, "cohesion": 0.0,
                                                 "work_of_adhesion": 0.0, "rolling_friction": 0.0,
                                                 "twisting_friction": 0.0, "tangential_restitution": 0.0}

    sim.set_contact_law("glass", "glass", friction=0.0)  # frictionless from now on
    v1 = sim.velocities[0, 0]
    sim.step(100)
    assert sim.velocities[0, 0] == pytest.approx(v1, rel=1e-12)


def test_a_fixed_grain_stays_put_until_freed():
    sim = rubble.Simulation(one_sphere(z=0.5))
    sim.fix(0)
    assert sim.is_fixed(0) and sim.is_fixed(1)
    sim.step(100)
    np.testing.assert_array_equal(sim.positions[0], [0.0, 0.0, 0.5])
    sim.free(0)
    sim.step(100)  # free fall for 0.01 s from rest (theta = 0.5: exact for a constant force)
    assert sim.positions[0, 2] == pytest.approx(0.5 - 0.5 * G0 * 0.01 ** 2, rel=1e-12)
    with pytest.raises(ValueError, match="wall"):
        sim.fix(1)


def test_run_callback_every_k_steps_and_stop():
    sim = rubble.Simulation(one_sphere())
    seen = []

    def callback(s):
        seen.append(s.step_count)
        return s.step_count < 30

    summary = sim.run(until=1.0, callback=callback, every=10)
    assert seen == [10, 20, 30]
    assert summary["stopped_by_callback"] and summary["steps"] == 30


def test_ctrl_c_stops_a_run_between_two_steps():
    sim = rubble.Simulation(one_sphere(end_time=1e3))
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        sim.run(until=1e3)  # 10^7 steps: far longer than the test
    timer.join()
    assert time.monotonic() - start < 30
    steps = sim.step_count
    assert steps > 0
    assert sim.time == pytest.approx(steps * sim.dt, rel=1e-9)  # stopped on a step boundary
    sim.step()  # and can go on
    assert sim.step_count == steps + 1


def test_steps_release_the_gil():
    # While one C++ call takes 3000 steps (about 0.3 s) in a thread, this thread keeps running Python and sees
    # the step count move: impossible if the GIL were held for the whole call.
    sim = rubble.Simulation(rubble.load_scene(os.path.join(os.path.dirname(__file__), "..", "..", "tests",
                                                           "postprocessing", "tiny_deposit.toml")))
    worker = threading.Thread(target=sim.step, args=(3000,))
    worker.start()
    seen = set()
    while worker.is_alive():
        seen.add(sim.step_count)
        time.sleep(1e-4)  # hands the GIL back at once (a busy loop would make the worker wait 5 ms a step)
    worker.join()
    assert sim.step_count == 3000
    assert len(seen) > 3, seen
    with pytest.raises(RuntimeError, match="another thread"):
        def step_twice():
            t = threading.Thread(target=sim.step, args=(1000,))
            t.start()
            try:
                while sim.step_count == 3000:
                    pass
                sim.step()
            finally:
                t.join()
        step_twice()


def test_branch_steps_on_independently():
    sim = rubble.Simulation(one_sphere())
    sim.step(20)
    sim.velocities = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    twin, other = sim.branch(), sim.branch()
    other.set_contact_law(0, 0, friction=0.0)
    for s in (sim, twin, other):
        s.step(50)
    assert twin.state_hash() == sim.state_hash()
    assert other.velocities[0, 0] > sim.velocities[0, 0]  # no friction: no deceleration


def test_checkpoint_keeps_a_changed_time_step_and_friction(tmp_path):
    sim = rubble.Simulation(one_sphere(friction=0.4))
    sim.step(20)
    sim.dt = 2e-4
    sim.set_contact_law("glass", "glass", friction=0.1)
    resumed = rubble.Simulation.from_checkpoint(sim.save_checkpoint(tmp_path))
    assert resumed.dt == 2e-4 and resumed.contact_law(0, 0)["friction"] == 0.1
    sim.step(30)
    resumed.step(30)
    np.testing.assert_array_equal(resumed.positions, sim.positions)


def test_kinetic_energy_metric_against_numpy():
    sim = rubble.Simulation(rubble.pack("cloud", n=40, dmin=2.0, dmax=3.0, seed=5))
    sim.step(5)
    m = sim.masses[:40]
    r = sim.bounding_radii[:40]
    v, w = sim.velocities[:40], sim.angular_velocities[:40]
    inertia = 0.4 * m * r ** 2  # solid spheres
    expected = 0.5 * np.sum(m * np.sum(v * v, axis=1)) + 0.5 * np.sum(inertia * np.sum(w * w, axis=1))
    metrics = sim.metrics()
    assert metrics["kinetic_energy"] == pytest.approx(expected, rel=1e-12)
    assert metrics["grains"] == 40
    x_cm = np.sum(m[:, None] * sim.positions[:40], axis=0) / np.sum(m)
    np.testing.assert_allclose([metrics[f"centre_of_mass_{c}"] for c in "xyz"], x_cm, rtol=1e-12, atol=1e-9)
    d_max = 2 * np.max(np.linalg.norm(sim.positions[:40] - x_cm, axis=1) + r)
    assert metrics["aggregate_diameter"] == pytest.approx(d_max, rel=1e-12)


def test_numerical_failure_is_raised_with_the_step():
    sim = rubble.Simulation(one_sphere(gravity=False, z=1.0))
    sim.velocities[0, 0] = np.inf  # the view writes anything; the next step reports it
    with pytest.raises(rubble.NumericalFailure, match=r"step 1 .*body 0"):
        sim.step()
    with pytest.raises(ValueError, match="not finite"):
        sim.velocities = np.full((2, 3), np.nan)  # assignment through the property is checked


def test_a_scene_with_an_inflow_is_refused_with_the_reason():
    # Its grains enter in the run loop of `rubble run` (simulation/inflow.hpp), not between
    # Simulation.step() calls: refused rather than stepped with its grains waiting in the region.
    scene = {
        "time": {"dt": 1e-4, "end_time": 0.01},
        "materials": [{"name": "glass", "density": 2500.0}],
        "default_contact_law": {"friction": 0.5},
        "walls": [{"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}],
        "inflow": [{"count": 5, "rate": 100.0, "distribution": "monodisperse", "radius": 0.01,
                    "region_min": [-0.1, -0.1, 0.1], "region_max": [0.1, 0.1, 0.2]}],
    }
    with pytest.raises(ValueError, match=r"\[\[inflow\]\] entries, which only `rubble run` inserts"):
        rubble.Simulation(rubble.scene_from_dict(scene))
