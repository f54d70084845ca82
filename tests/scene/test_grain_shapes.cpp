// Tests of preprocessing/grain_shapes.cpp: the smallest enclosing sphere against shapes whose
// ball is known and against every other candidate centre, uniform random rotations, and random
// polyhedra placed inside their packed ball.
#include "preprocessing/grain_shapes.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace rubble {
namespace {

double farthest(const std::vector<Vec3>& points, const Vec3& centre) {
  double r = 0.0;
  for (const Vec3& p : points) r = std::max(r, (p - centre).norm());
  return r;
}

TEST(MinimalEnclosingSphere, KnownBalls) {
  // A regular tetrahedron inscribed in the unit sphere: the ball is the unit ball, centre 0.
  const std::vector<Vec3> tetrahedron = {Vec3(1, 1, 1) / std::sqrt(3.0), Vec3(1, -1, -1) / std::sqrt(3.0),
                                         Vec3(-1, 1, -1) / std::sqrt(3.0), Vec3(-1, -1, 1) / std::sqrt(3.0)};
  EnclosingSphere ball = minimal_enclosing_sphere(tetrahedron);
  EXPECT_NEAR(ball.radius, 1.0, 1e-12);
  EXPECT_LT(ball.center.norm(), 1e-12);
  // Two far points and a cloud between them: the ball is that of the pair.
  std::vector<Vec3> segment = {Vec3(-3, 0, 0), Vec3(3, 0, 0), Vec3(0, 1, 0), Vec3(1, 0, 2), Vec3(-2, 0.5, 0.5)};
  ball = minimal_enclosing_sphere(segment);
  EXPECT_NEAR(ball.radius, 3.0, 1e-12);
  EXPECT_LT(ball.center.norm(), 1e-12);
  // A single point, and collinear points.
  EXPECT_EQ(minimal_enclosing_sphere({Vec3(1, 2, 3)}).radius, 0.0);
  EXPECT_NEAR(minimal_enclosing_sphere({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(4, 0, 0)}).radius, 2.0, 1e-12);
  EXPECT_THROW(minimal_enclosing_sphere({}), std::invalid_argument);
}

// Optimality on random clouds: every point is inside, and moving the centre by 1% of the radius
// in any of 200 directions never gives a smaller enclosing radius (the minimum is unique).
TEST(MinimalEnclosingSphere, EnclosesAndIsLocallyMinimalOnRandomClouds) {
  std::mt19937_64 rng(42);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<Vec3> points(10 + trial);
    for (Vec3& p : points) p = Vec3(uniform_01(rng), 2.0 * uniform_01(rng), 0.5 * uniform_01(rng));
    const EnclosingSphere ball = minimal_enclosing_sphere(points);
    EXPECT_NEAR(farthest(points, ball.center), ball.radius, 1e-12);
    for (int k = 0; k < 200; ++k) {
      const Vec3 direction = random_rotation(rng) * Vec3::UnitX();
      EXPECT_GE(farthest(points, ball.center + 0.01 * ball.radius * direction), ball.radius * (1.0 - 1e-12));
    }
  }
}

// Uniform over SO(3): the rotated x axis is uniform on the sphere, so its mean is 0 and the
// mean of each squared component is 1/3 (n = 20000: standard errors 0.004 and 0.002; tolerances 0.02).
TEST(RandomRotation, UnitAndUniform) {
  std::mt19937_64 rng(8);
  Vec3 mean = Vec3::Zero();
  Vec3 mean_square = Vec3::Zero();
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const Quat q = random_rotation(rng);
    EXPECT_NEAR(q.norm(), 1.0, 1e-14);
    const Vec3 x = q * Vec3::UnitX();
    mean += x / n;
    mean_square += x.cwiseProduct(x) / n;
  }
  EXPECT_LT(mean.norm(), 0.02);
  for (int axis = 0; axis < 3; ++axis) EXPECT_NEAR(mean_square[axis], 1.0 / 3.0, 0.02);
}

TEST(RandomPolyhedronInBall, EveryVertexInsideThePackedBallAndReproducible) {
  const PackedGrain grain{Vec3(10.0, -5.0, 2.0), 4.2};
  for (std::uint64_t seed = 1; seed <= 30; ++seed) {
    const PlacedPolyhedron placed = random_polyhedron_in_ball(grain, RandomPolyhedronOptions{}, seed);
    double reach = 0.0;
    for (const Vec3& v : placed.shape.vertices) {
      reach = std::max(reach, (placed.position + placed.orientation * v - grain.position).norm());
    }
    EXPECT_LE(reach, grain.radius * (1.0 + 1e-12)) << seed;
    // The circumscribed diameter is the packed one (the generator rescales to it).
    EXPECT_GT(reach, grain.radius * (1.0 - 1e-9)) << seed;
    const PlacedPolyhedron again = random_polyhedron_in_ball(grain, RandomPolyhedronOptions{}, seed);
    EXPECT_EQ(again.position, placed.position);
    EXPECT_EQ(again.orientation.coeffs(), placed.orientation.coeffs());
    EXPECT_EQ(again.shape.vertices.size(), placed.shape.vertices.size());
  }
}

}  // namespace
}  // namespace rubble
