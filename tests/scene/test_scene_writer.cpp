// Tests of the scene writer (simulation/scene_writer.cpp): scene_to_toml round-trips bit for bit,
// driven walls and bodies included.
#include "simulation/run_control.hpp"
#include "simulation/scene_file.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <numbers>

#include "scene/scene_test_scenes.hpp"

namespace rubble {
namespace {

using scene_test::cloud_scene;
using scene_test::read_text;
using scene_test::two_grains_in_a_box;

/// Same model and state, bit for bit.
void expect_same_scene(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.run.seed, b.run.seed);
  EXPECT_EQ(a.run.end_time, b.run.end_time);
  EXPECT_EQ(a.run.step.integrator.time_step, b.run.step.integrator.time_step);
  EXPECT_EQ(a.run.step.integrator.theta, b.run.step.integrator.theta);
  EXPECT_EQ(a.run.step.solver.tolerance, b.run.step.solver.tolerance);
  EXPECT_EQ(a.run.step.solver.warm_start, b.run.step.solver.warm_start);
  EXPECT_EQ(a.run.step.gravity.kind, b.run.step.gravity.kind);
  EXPECT_EQ(a.run.step.gravity.acceleration, b.run.step.gravity.acceleration);
  EXPECT_EQ(a.run.output.directory, b.run.output.directory);
  EXPECT_EQ(a.run.output.snapshot_every_steps, b.run.output.snapshot_every_steps);
  EXPECT_EQ(a.run.output.snapshot_interval, b.run.output.snapshot_interval);
  EXPECT_EQ(a.run.output.write_vtk, b.run.output.write_vtk);
  ASSERT_EQ(a.model.body_count(), b.model.body_count());
  EXPECT_EQ(a.model.shape_kind, b.model.shape_kind);
  EXPECT_EQ(a.model.material, b.model.material);
  EXPECT_EQ(a.model.mass, b.model.mass);
  EXPECT_EQ(a.model.contact_laws.laws.size(), b.model.contact_laws.laws.size());
  for (std::size_t k = 0; k < a.model.contact_laws.laws.size(); ++k) {
    EXPECT_EQ(a.model.contact_laws.laws[k].friction_coefficient, b.model.contact_laws.laws[k].friction_coefficient);
    EXPECT_EQ(a.model.contact_laws.laws[k].normal_restitution, b.model.contact_laws.laws[k].normal_restitution);
  }
  for (std::size_t i = 0; i < a.model.body_count(); ++i) {
    EXPECT_EQ(a.model.bounding_radius[i], b.model.bounding_radius[i]) << i;
    EXPECT_EQ(a.state.position[i], b.state.position[i]) << i;
    EXPECT_EQ(a.state.orientation[i].coeffs(), b.state.orientation[i].coeffs()) << i;
    EXPECT_EQ(a.state.velocity[i], b.state.velocity[i]) << i;
    EXPECT_EQ(a.state.angular_velocity[i], b.state.angular_velocity[i]) << i;
  }
  for (std::size_t k = 0; k < a.model.planes.size(); ++k) EXPECT_EQ(a.model.planes[k].normal, b.model.planes[k].normal);
  for (std::size_t k = 0; k < a.model.boxes.size(); ++k) {
    EXPECT_EQ(a.model.boxes[k].half_extents, b.model.boxes[k].half_extents);
  }
}

TEST(SceneToToml, RoundTripsBitForBit) {
  for (const Scene& original : {parse_scene(two_grains_in_a_box, "two.toml"), default_scene()}) {
    const std::string text = scene_to_toml(original);
    const Scene again = parse_scene(text, "written.toml");
    expect_same_scene(original, again);
    EXPECT_EQ(scene_to_toml(again), text);  // and writing is stable
  }
}

// Driven walls and bodies (docs/scene-file.md, "Driven bodies"): a plane moving by a table, a box
// turning at a constant rate, a held grain and an impactor. They parse into prescribed motions with
// infinite mass, start at their prescribed velocities, and are written back bit for bit.
TEST(SceneToToml, DrivenWallsAndBodiesRoundTrip) {
  const Scene original = parse_scene(std::string(two_grains_in_a_box) + R"(
[[walls]]
type = "plane"
point = [0.0, 0.0, 5.0]
normal = [0.0, 0.0, -1.0]
motion = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.5, 0.0, 0.0, 0.25]]
material = "wall"
[[walls]]
type = "box"
center = [0.0, 0.0, 7.0]
half_extents = [0.1, 0.1, 0.1]
angular_velocity = [0.0, 0.0, 2.0]
material = "wall"
[[bodies]]
shape = "sphere"
radius = 0.05
position = [0.0, 0.0, 3.0]
driven = true
material = "rock"
[[bodies]]
shape = "sphere"
radius = 0.05
position = [0.0, 0.0, 4.0]
driven = true
velocity = [0.0, 0.0, -3.0]
material = "rock"
)",
                                     "driven.toml");
  const Model& model = original.model;
  ASSERT_EQ(model.driven_bodies.size(), 4u);
  for (const std::size_t b : model.driven_bodies) {
    EXPECT_TRUE(model.is_fixed(b));
    EXPECT_EQ(model.mass[b], 0.0);
  }
  const std::size_t impactor = model.driven_bodies[1];
  EXPECT_TRUE(model.is_grain(impactor));
  EXPECT_EQ(original.state.velocity[impactor], Vec3(0, 0, -3.0));
  EXPECT_EQ(model.driven_velocity(model.driven_bodies[2], 0.5).linear, Vec3(0, 0, -0.25));
  EXPECT_EQ(original.state.angular_velocity[model.driven_bodies[3]], Vec3(0, 0, 2.0));
  const std::string text = scene_to_toml(original);
  const Scene again = parse_scene(text, "written.toml");
  expect_same_scene(original, again);
  EXPECT_EQ(again.model.driven_bodies, model.driven_bodies);
  for (std::size_t k = 0; k < model.prescribed_motions.size(); ++k) {
    EXPECT_EQ(again.model.prescribed_motions[k].time, model.prescribed_motions[k].time);
    EXPECT_EQ(again.model.prescribed_motions[k].velocity, model.prescribed_motions[k].velocity);
    EXPECT_EQ(again.model.prescribed_motions[k].angular_velocity, model.prescribed_motions[k].angular_velocity);
  }
  EXPECT_EQ(scene_to_toml(again), text);
}

}  // namespace
}  // namespace rubble
