// [[initial_conditions]] (simulation/initial_conditions.hpp): the rigid motion given to a group of
// grains, checked against v = V + w x (x - c) to round-off; and a spinning self-gravitating
// aggregate keeping its angular momentum while its grains collide and rub (contact impulses act
// in equal and opposite pairs at one point, and pairwise central gravity exerts no net torque).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "simulation/scene_file.hpp"
#include "support/test_scene.hpp"

namespace rubble {
namespace {

/// Two materials, four grains on a line along x (two of each), one already moving.
const char* four_grains = R"([time]
dt = 1e-3
end_time = 1.0
[[materials]]
name = "rock"
density = 2000.0
[[materials]]
name = "ice"
density = 1000.0
[default_contact_law]
friction = 0.5
[[bodies]]
shape = "sphere"
radius = 0.1
position = [0.0, 0.0, 0.0]
material = "rock"
[[bodies]]
shape = "sphere"
radius = 0.1
position = [1.0, 0.0, 0.0]
material = "rock"
velocity = [0.0, 0.0, 3.0]
[[bodies]]
shape = "sphere"
radius = 0.1
position = [2.0, 0.0, 0.0]
material = "ice"
[[bodies]]
shape = "sphere"
radius = 0.1
position = [3.0, 0.0, 0.0]
material = "ice"
)";

TEST(InitialConditions, RigidRotationAboutTheCentreOfMassIsAddedToTheSelectedGrains) {
  // The rock grains (masses equal) have their centre of mass at x = 0.5.
  const Scene scene = parse_scene(std::string(four_grains) + R"(
[[initial_conditions]]
material = "rock"
angular_velocity = [0.0, 0.0, 2.0]
velocity = [0.0, 1.0, 0.0]
)",
                                  "spin.toml");
  EXPECT_EQ(scene.state.velocity[0], Vec3(0, 1 - 1.0, 0));  // w x (-0.5, 0, 0) = (0, -1, 0)
  EXPECT_EQ(scene.state.velocity[1], Vec3(0, 1 + 1.0, 3.0));
  EXPECT_EQ(scene.state.angular_velocity[1], Vec3(0, 0, 2.0));
  EXPECT_EQ(scene.state.velocity[2], Vec3::Zero());
  EXPECT_EQ(scene.state.angular_velocity[3], Vec3::Zero());
  ASSERT_EQ(scene.initial_conditions.size(), 1u);

  // A region and an explicit centre: only the grains at x = 2 and 3, about x = 2.
  const Scene boxed = parse_scene(std::string(four_grains) + R"(
[[initial_conditions]]
angular_velocity = [0.0, 0.0, 1.0]
center = [2.0, 0.0, 0.0]
region_min = [1.5, -1.0, -1.0]
region_max = [3.5, 1.0, 1.0]
)",
                                  "boxed.toml");
  EXPECT_EQ(boxed.state.velocity[1], Vec3(0, 0, 3.0));
  EXPECT_EQ(boxed.state.velocity[2], Vec3::Zero());
  EXPECT_EQ(boxed.state.velocity[3], Vec3(0, 1.0, 0));
}

/// Total angular momentum about the origin, sum m x x v + I w (spheres: I = 2/5 m r^2), kg m^2/s.
Vec3 angular_momentum(const testing::TestScene& s) {
  Vec3 total = Vec3::Zero();
  for (std::size_t b = 0; b < s.model.body_count(); ++b) {
    const double m = s.model.mass[b];
    total += m * s.state.position[b].cross(s.state.velocity[b]);
    total += s.model.principal_inertia[b].x() * s.state.angular_velocity[b];
  }
  return total;
}

// 27 spheres (radius 0.5 m, density 1, G = 1: a free-fall time of order 1 s) on a loose 3 x 3 x 3
// grid are set spinning at 0.3 rad/s about an axis through their centre of mass, and collapse
// under their own gravity into a frictional clump (mu = 0.5) over 3 s. Rotation must survive the
// collisions: the total angular momentum is conserved to round-off (1e-9 relative, the solver's
// tolerance is 1e-10) and the linear momentum stays zero.
TEST(InitialConditions, SpinningAggregateKeepsItsAngularMomentum) {
  testing::TestScene s(1.0, 0.5, 0.0);
  s.options.integrator.time_step = 1e-3;
  // Momenta are conserved whatever the iterate (every impulse change is applied to both bodies at
  // one point), so the default tolerance without the Newton polish and at most 100 sweeps a step
  // will do: the clump's steps otherwise take hundreds of sweeps (5.6 s of CPU in Release against
  // 1.5 s, and over 100 s under the sanitizers).
  s.options.solver.tolerance = 1e-4;
  s.options.solver.polish_after = 0;
  s.options.solver.max_iterations = 100;
  s.options.gravity.kind = GravitySettings::Kind::self;
  s.options.gravity.self_gravity.method = gravity::Method::direct;
  s.options.gravity.self_gravity.G = 1.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) s.sphere(0.5, Vec3(1.2 * (i - 1), 1.2 * (j - 1) + 0.05 * i, 1.2 * (k - 1)));
  InitialCondition spin;
  spin.angular_velocity = Vec3(0.1, 0.0, 0.3);
  ASSERT_FALSE(apply_initial_conditions(s.model, {spin}, s.state));
  const Vec3 start = angular_momentum(s);
  ASSERT_GT(start.norm(), 1.0);
  std::size_t most_contacts = 0;
  for (int step = 0; step < 3000; ++step) most_contacts = std::max(most_contacts, s.advance().contacts);
  EXPECT_GE(most_contacts, 27u) << "the grains never collapsed into contact";
  const double drift = (angular_momentum(s) - start).norm() / start.norm();
  std::printf("angular momentum: |L0| = %.6g kg m^2/s, relative change %.3g, most contacts %zu\n", start.norm(), drift,
              most_contacts);
  EXPECT_LT(drift, 1e-9);
  Vec3 momentum = Vec3::Zero();
  for (std::size_t b = 0; b < s.model.body_count(); ++b) momentum += s.model.mass[b] * s.state.velocity[b];
  EXPECT_LT(momentum.norm(), 1e-10 * start.norm());
}

}  // namespace
}  // namespace rubble
