// Metrics of an aggregate against hand-computed values.
#include "postprocessing/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/postprocessing/test_shapes.hpp"

namespace rubble {
namespace {

TEST(KineticEnergy, SphereTranslationPlusRotation) {
  Model model;
  model.materials = {{"rock", 2000.0}};
  add_sphere(model, 0.5, 0);
  State state;
  state.resize(1);
  state.velocity[0] = Vec3(1.0, -2.0, 2.0);        // |v|^2 = 9
  state.angular_velocity[0] = Vec3(0.0, 3.0, 4.0);  // |w|^2 = 25
  const double m = 2000.0 * 4.0 / 3.0 * M_PI * 0.125;
  const double expected = 0.5 * m * 9.0 + 0.5 * (0.4 * m * 0.25) * 25.0;
  EXPECT_NEAR(kinetic_energy(model, state), expected, 1e-12 * expected);
}

TEST(KineticEnergy, RotatedBoxUsesTheWorldInertiaTensor) {
  // E_rot = 1/2 w^T R diag(I) R^T w, with the tensor built explicitly here.
  Model model;
  model.materials = {{"rock", 1500.0}};
  const Vec3 half(1.0, 0.5, 0.25);
  add_polyhedron(model, test::box_polyhedron(half), test::box_volume(half), test::box_inertia_per_density(half), 0);
  add_plane_wall(model, Vec3::UnitZ(), 0);
  State state;
  state.resize(2);
  state.orientation[0] = Quat(Eigen::AngleAxisd(0.7, Vec3(1.0, -1.0, 2.0).normalized()));
  state.velocity[0] = Vec3(0.3, 0.0, 0.0);
  state.angular_velocity[0] = Vec3(0.2, -1.0, 0.5);
  state.velocity[1] = Vec3(5.0, 5.0, 5.0);  // a wall never contributes, whatever its velocity says
  const Mat3 rotation = state.orientation[0].toRotationMatrix();
  const Mat3 world_inertia = rotation * model.principal_inertia[0].asDiagonal() * rotation.transpose();
  const Vec3 w = state.angular_velocity[0];
  const double expected = 0.5 * model.mass[0] * 0.09 + 0.5 * w.dot(world_inertia * w);
  EXPECT_NEAR(kinetic_energy(model, state), expected, 1e-12 * expected);
}

}  // namespace
}  // namespace rubble
