#include <gtest/gtest.h>

#include <numbers>
#include <vector>

#include "core/model.hpp"

namespace rubble {
namespace {

TEST(Model, SphereMassAndInertiaFromDensity) {
  Model m;
  m.materials.push_back({"rock", 5164.0});
  const int id = add_sphere(m, 5.0, 0);
  const double mass = 5164.0 * 4.0 / 3.0 * std::numbers::pi * 125.0;
  EXPECT_NEAR(m.mass[static_cast<std::size_t>(id)], mass, 1e-9 * mass);
  EXPECT_NEAR(m.principal_inertia[0].x(), 0.4 * mass * 25.0, 1e-9 * mass);
  EXPECT_NEAR(m.inverse_mass[0] * m.mass[0], 1.0, 1e-15);
  EXPECT_TRUE(m.is_grain(0));
  EXPECT_FALSE(m.is_fixed(0));
}

TEST(Model, WallsHaveInfiniteMass) {
  Model m;
  m.materials.push_back({"steel", 7800.0});
  add_plane_wall(m, Vec3(0, 0, 2), 0);
  add_box_wall(m, Vec3(1, 1, 1), 0);
  for (std::size_t b = 0; b < 2; ++b) {
    EXPECT_TRUE(m.is_fixed(b));
    EXPECT_EQ(m.inverse_inertia[b], Vec3::Zero());
  }
  EXPECT_EQ(m.planes[0].normal, Vec3::UnitZ());  // normalised
}

// The bodies in play of a run with [[inflow]] (simulation/inflow.hpp): the first n bodies, each
// with its own per-body data; appending the rest body by body gives back the whole model.
TEST(Model, PrefixKeepsTheFirstBodiesAndEveryTable) {
  Model m;
  m.materials.push_back({"rock", 2500.0});
  add_sphere(m, 0.1, 0);
  add_plane_wall(m, Vec3(0, 0, 1), 0);
  add_sphere(m, 0.2, 0);
  drive_body(m, 0, PrescribedMotion{{0.0}, {Vec3(1, 0, 0)}, {Vec3::Zero()}});
  const Model two = model_prefix(m, 2);
  ASSERT_EQ(two.body_count(), 2u);
  for (const auto* column : {&two.mass, &two.inverse_mass, &two.bounding_radius, &two.volume}) {
    EXPECT_EQ(column->size(), 2u);
  }
  EXPECT_EQ(two.principal_inertia.size(), 2u);
  EXPECT_EQ(two.inverse_inertia.size(), 2u);
  EXPECT_EQ(two.shape_index, std::vector<int>(m.shape_index.begin(), m.shape_index.begin() + 2));
  EXPECT_EQ(two.motion_of_body, std::vector<int>({0, -1}));
  EXPECT_EQ(two.driven_bodies, std::vector<std::size_t>({0}));
  EXPECT_EQ(two.spheres.size(), 2u);  // the shape tables whole: the third body's shape is there
  EXPECT_EQ(two.mass[1], 0.0);
  const Model all = model_prefix(m, m.body_count());
  EXPECT_EQ(all.mass, m.mass);
  EXPECT_EQ(all.bounding_radius, m.bounding_radius);
  EXPECT_EQ(all.material, m.material);
  State state;
  state.resize(3);
  state.time = 2.5;
  state.position[2] = Vec3(0, 0, 7);
  const State first = state_prefix(state, 2);
  EXPECT_EQ(first.body_count(), 2u);
  EXPECT_EQ(first.time, 2.5);
  EXPECT_EQ(state_prefix(state, 3).position[2], Vec3(0, 0, 7));
}

TEST(ContactLawTable, IsSymmetric) {
  ContactLawTable t;
  t.reset(3, {0.1, 0.0});
  t.set(0, 2, {0.7, 0.4});
  EXPECT_EQ(t.get(2, 0).friction_coefficient, 0.7);
  EXPECT_EQ(t.get(0, 2).normal_restitution, 0.4);
  EXPECT_EQ(t.get(1, 1).friction_coefficient, 0.1);
}

}  // namespace
}  // namespace rubble
