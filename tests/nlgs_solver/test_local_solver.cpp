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

// The Newton started from a guess's slip direction (what a sweep passes: the current impulse)
// must still zero the natural map, whatever the guess: near the solution, opposite to it, or
// along the normal only (no direction: the sticking trial's).
TEST(LocalSolver, ZeroesTheNaturalMapFromAnyGuess) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int sliding = 0;
  for (int k = 0; k < 20000; ++k) {
    const Mat3 W = random_delassus(rng, k % 2 ? 0.3 : 1.0);
    const Vec3 q(u(rng), u(rng), u(rng));
    const double mu = std::abs(u(rng));
    const LocalSolution plain = solve_local_contact(W, q, mu);
    const Vec3 guesses[] = {plain.impulse + 0.1 * Vec3(u(rng), u(rng), u(rng)), -plain.impulse, Vec3(1.0, 0.0, 0.0),
                            Vec3(u(rng), u(rng), u(rng))};
    for (const Vec3& guess : guesses) {
      const LocalSolution s = solve_local_contact(W, W.inverse(), q, mu, guess);
      ASSERT_LT(natural_map(s.impulse, W * s.impulse + q, mu).norm(), 1e-9 * (1.0 + q.norm()))
          << "case " << k << " guess " << guess.transpose();
      ASSERT_EQ(s.regime, plain.regime) << "case " << k;
    }
    sliding += plain.regime == LocalSolution::Regime::sliding;
  }
  EXPECT_GT(sliding, 1000);
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

// The sweep's inline update (relaxed_local_update) against the law and the local solver: at
// omega = 1 its impulse zeroes the natural map of the local problem u = W r' + u_free; at omega =
// 1.5 it is the relaxed solution projected onto the cone; its change is the impulse less r. Blocks
// coupled and isotropic (the inline sliding form), friction 0 (the inline frictionless form) to 1,
// from admissible current impulses.
TEST(LocalSolver, SweepUpdateIsTheRelaxedLocalSolution) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int regimes[3] = {0, 0, 0};
  for (int k = 0; k < 20000; ++k) {
    Mat3 W = random_delassus(rng, 0.5);
    if (k % 2 == 1) {  // a sphere's block, as rounding leaves it
      W = Mat3::Zero();
      W(0, 0) = 1.0 + 0.9 * u(rng);
      W(1, 1) = W(2, 2) = 3.5 * (1.0 + 0.9 * u(rng));
      W(0, 1) = W(1, 0) = 1e-17 * u(rng);
    }
    const double mu = k % 5 == 0 ? 0.0 : std::abs(u(rng));
    const Vec3 r = project_onto_coulomb_cone(Vec3(u(rng), u(rng), u(rng)), mu);  // the current impulse
    const Vec3 velocity(u(rng), u(rng), u(rng));                                 // u for that impulse
    const Vec3 u_free = velocity - W * r;
    const Mat3 W_inverse = W.inverse();
    const double scale = 1.0 + u_free.norm() + r.norm();

    const LocalUpdate plain = relaxed_local_update(W, W_inverse, r, velocity, u_free, mu, 1.0);
    const LocalSolution exact = solve_local_contact(W, W_inverse, u_free, mu);
    ASSERT_LT(natural_map(plain.impulse, W * plain.impulse + u_free, mu).norm(), 1e-9 * scale) << "case " << k;
    ASSERT_LT((plain.impulse - exact.impulse).norm(), 1e-9 * scale) << "case " << k;
    ASSERT_LT((plain.change - (plain.impulse - r)).norm(), 1e-14 * scale) << "case " << k;
    ++regimes[static_cast<int>(exact.regime)];

    const LocalUpdate relaxed = relaxed_local_update(W, W_inverse, r, velocity, u_free, mu, 1.5);
    const Vec3 expected = project_onto_coulomb_cone(1.5 * exact.impulse - 0.5 * r, mu);
    ASSERT_LT((relaxed.impulse - expected).norm(), 1e-9 * scale) << "case " << k;
    ASSERT_LT((relaxed.change - (relaxed.impulse - r)).norm(), 1e-14 * scale) << "case " << k;
    const Vec3 projected = project_onto_coulomb_cone(relaxed.impulse, mu);
    ASSERT_LT((projected - relaxed.impulse).norm(), 1e-14 * scale) << "case " << k;  // admissible
  }
  for (const int count : regimes) EXPECT_GT(count, 1000);  // open, sticking and sliding all met
}

}  // namespace
}  // namespace rubble
