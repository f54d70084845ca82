// The local solver against the law itself: its answer must zero the natural map
// (an independent characterisation of Signorini-Coulomb, De Saxcé), branch by branch.
#include <gtest/gtest.h>

#include <random>

#include "nlgs_solver/coulomb.hpp"
#include "nlgs_solver/local_solver.hpp"

namespace rubble {
namespace {

Mat3 random_delassus(std::mt19937_64& rng, double coupling) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Mat3 a;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a(i, j) = coupling * u(rng);
  // Positive definite: A A^T plus a diagonal, the shape of H^T M^-1 H blocks.
  return a * a.transpose() + Mat3::Identity() * (0.2 + std::abs(u(rng)));
}

TEST(CoulombCone, ProjectionIsIdempotentAndOnTheCone) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int k = 0; k < 1000; ++k) {
    const Vec3 x(u(rng), u(rng), u(rng));
    const double mu = 0.25 * (2 + u(rng));  // in [0, 1]
    const Vec3 p = project_onto_coulomb_cone(x, mu);
    EXPECT_LE(std::hypot(p.y(), p.z()), mu * p.x() + 1e-12);
    EXPECT_LT((project_onto_coulomb_cone(p, mu) - p).norm(), 1e-12);
    // Moreau decomposition: x - P_K(x) is orthogonal to P_K(x).
    EXPECT_NEAR((x - p).dot(p), 0.0, 1e-12);
  }
}

// mu = 0: the cone is the half-line x_T = 0, x_n >= 0, so the projection of (x_n, 0, 0) is
// (max(x_n, 0), 0, 0), and an open frictionless contact has a zero natural map even when its
// tangential velocity is exactly zero (a head-on approach): F = r - P(r - u) = 0 for r = 0, u_n > 0.
TEST(CoulombCone, FrictionlessConeIsTheNonNegativeNormalHalfLine) {
  EXPECT_EQ(project_onto_coulomb_cone(Vec3(-1.0, 0.0, 0.0), 0.0), Vec3::Zero());
  EXPECT_EQ(project_onto_coulomb_cone(Vec3(2.0, 0.0, 0.0), 0.0), Vec3(2.0, 0.0, 0.0));
  EXPECT_EQ(project_onto_coulomb_cone(Vec3(2.0, 1.0, -3.0), 0.0), Vec3(2.0, 0.0, 0.0));
  EXPECT_EQ(project_onto_coulomb_cone(Vec3(-2.0, 1.0, -3.0), 0.0), Vec3::Zero());
  EXPECT_EQ(natural_map(Vec3::Zero(), Vec3(0.5, 0.0, 0.0), 0.0, 3.0), Vec3::Zero());
  EXPECT_EQ(natural_map(Vec3::Zero(), Vec3(0.5, 0.2, 0.0), 0.0, 3.0), Vec3::Zero());
  // A loaded contact still has the natural map of its normal velocity.
  EXPECT_DOUBLE_EQ(natural_map(Vec3(1.0, 0.0, 0.0), Vec3(0.5, 0.0, 0.0), 0.0, 3.0).x(), 0.5);
}

TEST(LocalSolver, OpenWhenTheFreeVelocitySeparates) {
  const LocalSolution s = solve_local_contact(Mat3::Identity(), Vec3(0.1, 3.0, -2.0), 0.5);
  EXPECT_EQ(s.impulse, Vec3::Zero());
  EXPECT_EQ(s.regime, LocalSolution::Regime::open);
}

TEST(LocalSolver, SticksInsideTheCone) {
  const LocalSolution s = solve_local_contact(Mat3::Identity(), Vec3(-1.0, 0.3, 0.0), 0.5);
  EXPECT_EQ(s.regime, LocalSolution::Regime::sticking);
  EXPECT_LT((s.impulse - Vec3(1.0, -0.3, 0.0)).norm(), 1e-14);
}

TEST(LocalSolver, SlidesOnTheConeOpposingTheSlip) {
  // Isotropic block: r_n = 1, r_T = -mu r_n along the slip, slip speed 2 - 0.5 = 1.5.
  const LocalSolution s = solve_local_contact(Mat3::Identity(), Vec3(-1.0, 2.0, 0.0), 0.5);
  EXPECT_EQ(s.regime, LocalSolution::Regime::sliding);
  EXPECT_LT((s.impulse - Vec3(1.0, -0.5, 0.0)).norm(), 1e-14);
}

TEST(LocalSolver, ZeroesTheNaturalMapOnRandomCoupledBlocks) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int sliding = 0;
  for (int k = 0; k < 20000; ++k) {
    const Mat3 W = random_delassus(rng, k % 2 ? 0.3 : 1.0);
    const Vec3 q(u(rng), u(rng), u(rng));
    const double mu = 1.0 * std::abs(u(rng));
    const LocalSolution s = solve_local_contact(W, q, mu);
    const Vec3 velocity = W * s.impulse + q;
    const double scale = 1.0 + q.norm();
    ASSERT_LT(natural_map(s.impulse, velocity, mu).norm(), 1e-9 * scale) << "case " << k << " mu " << mu << "\nW\n"
                                                                         << W << "\nq " << q.transpose();
    sliding += s.regime == LocalSolution::Regime::sliding;
  }
  EXPECT_GT(sliding, 1000);  // the sliding branch was exercised
}

// Sphere blocks (W_nT = 0, W_TT = w I, up to rounding-sized off-diagonal terms) take the closed
// form; the same blocks made anisotropic by 1e-8 take the Newton path. Both must zero the natural
// map and agree to the size of that anisotropy.
TEST(LocalSolver, ClosedFormOnIsotropicBlocksAgreesWithTheNewtonPath) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int sliding = 0;
  for (int k = 0; k < 5000; ++k) {
    const double normal = 1.0 + 0.9 * u(rng), tangential = 3.5 * (1.0 + 0.9 * u(rng));
    Mat3 W = Mat3::Zero();
    W(0, 0) = normal;
    W(1, 1) = W(2, 2) = tangential;
    W(0, 1) = W(1, 0) = 1e-17 * u(rng);  // what rounding leaves of a sphere pair's coupling
    W(1, 2) = W(2, 1) = 1e-17 * u(rng);
    Mat3 anisotropic = W;
    anisotropic(2, 2) *= 1.0 + 1e-8;
    const Vec3 q(u(rng), 3.0 * u(rng), 3.0 * u(rng));
    const double mu = std::abs(u(rng));
    const LocalSolution closed = solve_local_contact(W, q, mu);
    const LocalSolution newton = solve_local_contact(anisotropic, q, mu);
    ASSERT_EQ(closed.regime, newton.regime) << "case " << k;
    const double scale = 1.0 + q.norm();
    ASSERT_LT(natural_map(closed.impulse, W * closed.impulse + q, mu).norm(), 1e-12 * scale) << "case " << k;
    ASSERT_LT((closed.impulse - newton.impulse).norm(), 1e-7 * scale) << "case " << k;
    sliding += closed.regime == LocalSolution::Regime::sliding;
  }
  EXPECT_GT(sliding, 1000);
}

}  // namespace
}  // namespace rubble
