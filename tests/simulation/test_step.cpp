// Physics of one sphere or a few, stepped by the full pipeline, against closed-form references.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;
constexpr double g = 9.81;

// Free fall under the theta-method: v_N = v_0 + N h g and, summing x_{k+1} = x_k + h((1-theta) v_k
// + theta v_{k+1}), x_N = x_0 + N h v_0 + g h^2 (N(N-1)/2 + theta N). Exact to round-off.
TEST(FreeFall, MatchesTheMoreauJeanRecurrenceAfterOneSecond) {
  for (const double theta : {0.5, 0.75, 1.0}) {
    TestScene s;
    s.uniform_gravity(g);
    s.options.integrator.theta = theta;
    const Vec3 v0(0.3, -0.2, 1.0);
    s.sphere(0.1, Vec3(0, 0, 10), v0);
    const double h = s.options.integrator.time_step;
    const long n = 10000;
    s.steps(n);
    const double expected_z = 10 + n * h * v0.z() - g * h * h * (n * (n - 1) / 2.0 + theta * n);
    EXPECT_NEAR(s.state.position[0].z(), expected_z, 1e-10) << "theta " << theta;
    EXPECT_NEAR(s.state.position[0].x(), n * h * v0.x(), 1e-12);
    EXPECT_NEAR(s.state.velocity[0].z(), v0.z() - n * h * g, 1e-10);
    EXPECT_NEAR(s.state.time, 1.0, 1e-9);
  }
}

// A sphere placed exactly on a plane stays there: Signorini with zero gap gives r_n = m g h.
TEST(RestingSphere, NoDriftAndPenetrationBelowOneMillionthOfTheRadius) {
  TestScene s(2500, 0.5, 0.0);
  s.uniform_gravity(g);
  const double radius = 0.1;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  const int ball = s.sphere(radius, Vec3(0.2, -0.1, radius));
  double worst_penetration = 0.0;
  for (int k = 0; k < 10000; ++k) {
    s.advance();
    worst_penetration = std::max(worst_penetration, radius - s.state.position[ball].z());
  }
  EXPECT_LT(worst_penetration, 1e-6 * radius);
  EXPECT_LT((s.state.position[ball] - Vec3(0.2, -0.1, radius)).norm(), 1e-6 * radius);
  EXPECT_LT(s.state.velocity[ball].norm(), 1e-9);
}

// Newton restitution: successive apex heights (of the gap) are in ratio e^2.
TEST(Bounce, ApexHeightsFallByRestitutionSquared) {
  for (const double e : {0.5, 0.8}) {
    TestScene s(2500, 0.0, e);
    s.uniform_gravity(g);
    const double radius = 0.1;
    s.plane(Vec3::Zero(), Vec3::UnitZ());
    const int ball = s.sphere(radius, Vec3(0, 0, radius + 1.0));
    std::vector<double> apexes{1.0};
    double previous_vz = 0.0;
    while (apexes.size() < 4 && s.state.time < 10.0) {
      s.advance();
      const double vz = s.state.velocity[ball].z();
      if (previous_vz > 0.0 && vz <= 0.0) apexes.push_back(s.state.position[ball].z() - radius);
      previous_vz = vz;
    }
    ASSERT_EQ(apexes.size(), 4u) << "e = " << e;
    for (std::size_t k = 1; k < apexes.size(); ++k) {
      EXPECT_NEAR(apexes[k] / apexes[k - 1], e * e, 0.01 * e * e) << "e = " << e << ", bounce " << k;
    }
  }
}

// Sphere on an incline from rest. Rolling without slipping needs |f| = (2/7) m g sin(a) <= mu m g
// cos(a), i.e. tan(a) <= 3.5 mu: then a = (5/7) g sin(a); above it slides with
// a = g (sin(a) - mu cos(a)) and spins up at dw/dt = (5/2) mu g cos(a) / r.
struct InclineResult {
  double acceleration;
  double angular_acceleration;
};
InclineResult roll_down_incline(double angle, double mu, double duration) {
  TestScene s(2500, mu, 0.0);
  s.uniform_gravity(g);
  const double radius = 0.05;
  const Vec3 normal(std::sin(angle), 0.0, std::cos(angle));
  s.plane(Vec3::Zero(), normal);
  const int ball = s.sphere(radius, radius * normal);
  s.run(duration);
  const Vec3 down_slope = Vec3(g * normal.z() * normal.x(), 0, -g + g * normal.z() * normal.z()).normalized();
  const double distance = (s.state.position[ball] - radius * normal).dot(down_slope);
  return {2.0 * distance / (duration * duration), s.state.angular_velocity[ball].norm() / duration};
}

TEST(Incline, RollsWithoutSlippingBelowTheThreshold) {
  const double angle = 30.0 * std::numbers::pi / 180.0;  // tan = 0.577 < 3.5 * 0.3
  const InclineResult r = roll_down_incline(angle, 0.3, 0.5);
  const double expected = 5.0 / 7.0 * g * std::sin(angle);
  EXPECT_NEAR(r.acceleration, expected, 0.01 * expected);
  EXPECT_NEAR(r.angular_acceleration, expected / 0.05, 0.01 * expected / 0.05);  // rolling: a = r dw/dt
}

TEST(Incline, SlidesAboveTheThreshold) {
  const double angle = 30.0 * std::numbers::pi / 180.0;  // tan = 0.577 > 3.5 * 0.1
  const double mu = 0.1;
  const InclineResult r = roll_down_incline(angle, mu, 0.5);
  const double expected = g * (std::sin(angle) - mu * std::cos(angle));
  EXPECT_NEAR(r.acceleration, expected, 0.01 * expected);
  const double expected_spin = 2.5 * mu * g * std::cos(angle) / 0.05;
  EXPECT_NEAR(r.angular_acceleration, expected_spin, 0.01 * expected_spin);
}

TEST(Incline, JustBelowAndJustAboveTheRollingThreshold) {
  const double mu = 0.2;
  const double threshold = std::atan(3.5 * mu);
  for (const double factor : {0.97, 1.03}) {
    const double angle = factor * threshold;
    const InclineResult r = roll_down_incline(angle, mu, 0.3);
    const double expected =
        factor < 1 ? 5.0 / 7.0 * g * std::sin(angle) : g * (std::sin(angle) - mu * std::cos(angle));
    EXPECT_NEAR(r.acceleration, expected, 0.01 * expected) << "angle factor " << factor;
  }
}

// Ten spheres stacked in a square tube of four walls on a floor, touching: nothing moves.
TEST(Column, TenStackedSpheresBetweenWallsStayAtRest) {
  TestScene s(2500, 0.5, 0.0);
  s.uniform_gravity(g);
  const double radius = 0.05;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  s.plane(Vec3(-radius, 0, 0), Vec3::UnitX());
  s.plane(Vec3(radius, 0, 0), -Vec3::UnitX());
  s.plane(Vec3(0, -radius, 0), Vec3::UnitY());
  s.plane(Vec3(0, radius, 0), -Vec3::UnitY());
  std::vector<int> balls;
  for (int k = 0; k < 10; ++k) balls.push_back(s.sphere(radius, Vec3(0, 0, radius * (2 * k + 1))));
  s.options.solver.tolerance = 1e-8;
  int max_iterations = 0;
  for (int k = 0; k < 5000; ++k) {
    s.advance();
    max_iterations = std::max(max_iterations, s.last_report.solver.iterations);
  }
  for (int k = 0; k < 10; ++k) {
    const Vec3 initial(0, 0, radius * (2 * k + 1));
    EXPECT_LT((s.state.position[static_cast<std::size_t>(balls[static_cast<std::size_t>(k)])] - initial).norm(),
              1e-6 * radius)
        << "sphere " << k;
  }
  EXPECT_TRUE(s.last_report.solver.converged);
  RecordProperty("max_nlgs_iterations", max_iterations);
  std::cout << "column of 10: max NLGS iterations per step " << max_iterations << ", residual "
            << s.last_report.solver.residual << "\n";
}

// Equal spheres, head-on, e = 1: velocities exchanged, momentum conserved.
TEST(HeadOn, ElasticEqualMassesExchangeVelocities) {
  TestScene s(2500, 0.3, 1.0);
  const double radius = 0.1;
  const int a = s.sphere(radius, Vec3(-0.5, 0, 0), Vec3(2.0, 0, 0));
  const int b = s.sphere(radius, Vec3(0.5, 0, 0), Vec3(-0.5, 0, 0));
  const double mass = s.model.mass[0];
  const Vec3 momentum_before = mass * (s.state.velocity[0] + s.state.velocity[1]);
  s.run(1.0);
  const Vec3 momentum_after = mass * (s.state.velocity[0] + s.state.velocity[1]);
  EXPECT_NEAR(s.state.velocity[static_cast<std::size_t>(a)].x(), -0.5, 1e-9);
  EXPECT_NEAR(s.state.velocity[static_cast<std::size_t>(b)].x(), 2.0, 1e-9);
  EXPECT_LT((momentum_after - momentum_before).norm(), 1e-12 * momentum_before.norm());
}

}  // namespace
}  // namespace rubble
