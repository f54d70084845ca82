#include <gtest/gtest.h>

#include <numbers>

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
