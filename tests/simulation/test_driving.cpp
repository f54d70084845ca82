// Driven bodies (core/model.hpp, PrescribedMotion): walls and grains that move with a prescribed
// velocity, push grains and are not pushed (infinite mass in the solver). Each test compares with
// a closed form: the knot table's interpolation, the integral of a prescribed velocity, a grain
// pushed by a plate at the plate's speed, a grain struck head-on by an elastic impactor of infinite
// mass leaving at twice its speed, and a turning paddle that must meet a grain its first pair list
// did not hold.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

TEST(PrescribedMotion, LinearBetweenKnotsHeldOutside) {
  const PrescribedMotion motion{{1.0, 3.0}, {Vec3::Zero(), Vec3(2, 0, 0)}, {Vec3(0, 0, 1), Vec3(0, 0, -1)}};
  EXPECT_EQ(prescribed_velocity(motion, 0.0).linear, Vec3::Zero());
  EXPECT_EQ(prescribed_velocity(motion, 0.0).angular, Vec3(0, 0, 1));
  EXPECT_EQ(prescribed_velocity(motion, 2.0).linear, Vec3(1, 0, 0));
  EXPECT_EQ(prescribed_velocity(motion, 2.0).angular, Vec3::Zero());
  EXPECT_EQ(prescribed_velocity(motion, 2.5).linear, Vec3(1.5, 0, 0));
  EXPECT_EQ(prescribed_velocity(motion, 9.0).linear, Vec3(2, 0, 0));
  EXPECT_EQ(prescribed_velocity(motion, 9.0).angular, Vec3(0, 0, -1));
}

TEST(PrescribedMotion, DriveBodyRefusesMalformedMotions) {
  Model model;
  model.materials.push_back(Material{"m", 1.0});
  const int ball = add_sphere(model, 0.1, 0);
  EXPECT_THROW(
      drive_body(model, ball, PrescribedMotion{{0.0, 0.0}, {Vec3::Zero(), Vec3::Zero()}, {Vec3::Zero(), Vec3::Zero()}}),
      std::invalid_argument);
  EXPECT_THROW(drive_body(model, ball, PrescribedMotion{{0.0}, {}, {Vec3::Zero()}}), std::invalid_argument);
  EXPECT_FALSE(model.is_driven(0));
  drive_body(model, ball, PrescribedMotion{{0.0}, {Vec3::UnitX()}, {Vec3::Zero()}});
  EXPECT_TRUE(model.is_driven(0));
  EXPECT_TRUE(model.is_fixed(0));  // infinite mass for the solver
  EXPECT_THROW(drive_body(model, ball, PrescribedMotion{{0.0}, {Vec3::UnitX()}, {Vec3::Zero()}}),
               std::invalid_argument);
}

// v(t) = t on [0, 1], then 1: the wall travels t^2 / 2, then 1/2 + (t - 1). With the knots on step
// boundaries the step's trapezoidal rule is exact, so the position must match to round-off; a
// constant spin about z turns a box wall by w t exactly.
TEST(Driving, WallTravelsTheIntegralOfItsPrescribedVelocity) {
  TestScene s;
  s.options.integrator.time_step = 1e-3;
  s.sphere(0.1, Vec3(10, 10, 10));
  const int floor = s.plane(Vec3::Zero(), Vec3::UnitZ());
  const int paddle = s.box_wall(Vec3(-10, -10, -10), Vec3(0.5, 0.1, 0.1));
  s.drive(floor, PrescribedMotion{{0.0, 1.0}, {Vec3::Zero(), Vec3::UnitZ()}, {Vec3::Zero(), Vec3::Zero()}});
  s.drive(paddle, Vec3::Zero(), Vec3(0, 0, 0.5));
  s.steps(500);
  EXPECT_NEAR(s.state.position[static_cast<std::size_t>(floor)].z(), 0.125, 1e-12);
  s.steps(1500);
  EXPECT_NEAR(s.state.position[static_cast<std::size_t>(floor)].z(), 1.5, 1e-12);
  EXPECT_NEAR(s.state.velocity[static_cast<std::size_t>(floor)].z(), 1.0, 1e-15);
  const Quat expected(Eigen::AngleAxisd(0.5 * 2.0, Vec3::UnitZ()));
  EXPECT_NEAR(s.state.orientation[static_cast<std::size_t>(paddle)].angularDistance(expected), 0.0, 1e-12);
  EXPECT_EQ(s.state.position[static_cast<std::size_t>(paddle)], Vec3(-10, -10, -10));
}

// A plate at 0.5 m/s meets a grain at rest (no gravity, no friction, e = 0): from then on the
// grain moves at exactly the plate's speed, touching it, and the plate does not slow down.
TEST(Driving, PlatePushesAGrainAtThePlatesSpeed) {
  TestScene s;
  const double speed = 0.5, radius = 0.05;
  const int grain = s.sphere(radius, Vec3(0.2, 0, 0));
  const int plate = s.box_wall(Vec3(0.1, 0, 0), Vec3(0.02, 0.2, 0.2));
  s.drive(plate, Vec3(speed, 0, 0));
  s.run(0.5);
  const auto g = static_cast<std::size_t>(grain), p = static_cast<std::size_t>(plate);
  EXPECT_NEAR(s.state.position[p].x(), 0.1 + speed * 0.5, 1e-12);
  EXPECT_NEAR(s.state.velocity[g].x(), speed, 1e-9);
  EXPECT_NEAR(s.state.velocity[g].norm(), speed, 1e-9);
  // Touching: neither left behind nor pushed through. The overlap left at the first touch stays
  // within the solver's allowed_overlap (1e-3 of the radius), which no recovery removes.
  const double gap = s.state.position[g].x() - radius - (s.state.position[p].x() + 0.02);
  EXPECT_LE(gap, 1e-9);
  EXPECT_GE(gap, -s.options.solver.overlap_recovery.allowed_overlap * radius);
  EXPECT_EQ(s.state.velocity[p], Vec3(speed, 0, 0));
}

// An elastic (e = 1) head-on impact of a body of infinite mass moving at v0 on a grain at rest:
// the relative normal velocity reverses, so the grain leaves at 2 v0 (the limit m1/m2 -> inf of
// the elastic collision); the impactor goes on at v0. Frictionless, no gravity.
TEST(Driving, ElasticImpactorOfInfiniteMassSendsAGrainOffAtTwiceItsSpeed) {
  TestScene s(2500.0, 0.0, 1.0);
  const double v0 = 1.0;
  const int impactor = s.sphere(0.05, Vec3(0, 0, 0));
  const int grain = s.sphere(0.05, Vec3(0.2, 0, 0));
  s.drive(impactor, Vec3(v0, 0, 0));
  s.run(0.2);
  const auto i = static_cast<std::size_t>(impactor), g = static_cast<std::size_t>(grain);
  EXPECT_NEAR(s.state.velocity[g].x(), 2.0 * v0, 1e-9);
  EXPECT_NEAR(s.state.velocity[g].tail<2>().norm(), 0.0, 1e-12);
  EXPECT_EQ(s.state.velocity[i], Vec3(v0, 0, 0));
  EXPECT_NEAR(s.state.position[i].x(), 0.2 * v0, 1e-12);
}

// A paddle turning about z at 1 rad/s (a box wall, driven) reaches a grain that lay far outside its
// bounding box when the first pair list was built. The paddle's centre never moves, so only its
// turning can renew the pair list; without that the paddle passes through the grain. With it the
// grain is struck: it moves, and it never sinks into the paddle by more than the solver's slack.
TEST(Driving, TurningPaddleStrikesAGrainItsFirstPairListDidNotHold) {
  TestScene s;
  const double radius = 0.05;
  const int grain = s.sphere(radius, Vec3(0.3, 0.3, 0));
  const int paddle = s.box_wall(Vec3::Zero(), Vec3(0.5, 0.02, 0.1));
  s.drive(paddle, Vec3::Zero(), Vec3(0, 0, 1.0));
  const auto g = static_cast<std::size_t>(grain), p = static_cast<std::size_t>(paddle);
  double deepest = 0.0;
  for (int k = 0; k < 12000; ++k) {  // 1.2 s: the paddle turns by 69 degrees, past the grain at 45
    s.advance();
    // Distance of the grain's centre from the paddle's mid-plane, minus the half-thickness.
    const Vec3 across = s.state.orientation[p] * Vec3::UnitY();
    const Vec3 along = s.state.orientation[p] * Vec3::UnitX();
    if (std::abs(along.dot(s.state.position[g] - s.state.position[p])) < 0.5) {
      deepest = std::min(deepest, std::abs(across.dot(s.state.position[g] - s.state.position[p])) - 0.02 - radius);
    }
  }
  EXPECT_GT(s.state.velocity[g].norm(), 0.1) << "the paddle never struck the grain";
  EXPECT_GT(deepest, -1e-4) << "the grain sank into the paddle";
}

}  // namespace
}  // namespace rubble
