// The file-backed (W, q, mu) problem: solved by the simulation's sweep to the FCLib error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "nlgs_solver/local_problem.hpp"

namespace rubble {
namespace {

// Dense SPD W of n contacts stored as CSR.
LocalProblem random_problem(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int m = static_cast<int>(3 * n);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(m, m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) a(i, j) = u(rng) * (i / 3 == j / 3 ? 1.0 : 0.15);
  const Eigen::MatrixXd W = a * a.transpose() + Eigen::MatrixXd::Identity(m, m);
  LocalProblem p;
  p.W.rows = p.W.columns = m;
  p.W.row_start.push_back(0);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) {
      p.W.column.push_back(j);
      p.W.value.push_back(W(i, j));
    }
    p.W.row_start.push_back(static_cast<int>(p.W.value.size()));
  }
  for (int i = 0; i < m; ++i) p.q.push_back(u(rng) - (i % 3 == 0 ? 0.5 : 0.0));
  for (std::size_t k = 0; k < n; ++k) p.mu.push_back(0.3 + 0.3 * std::abs(u(rng)));
  return p;
}

TEST(LocalProblem, ConvergesToTheFclibErrorOnRandomProblems) {
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const LocalProblem p = random_problem(12, seed);
    LocalProblemOptions options;
    options.tolerance = 1e-10;
    const LocalProblemSolution s = solve_local_problem(p, options);
    EXPECT_TRUE(s.converged) << "seed " << seed << " error " << s.error;
    // Independent check of the returned pair: u = W r + q and the error recomputed here.
    EXPECT_LE(fclib_error(p, s.r, s.u), 1e-10);
  }
}

// One contact, W = diag(2, 1, 1), q = (-1, 0.5, 0), mu = 0.1 (solution r = (0.5, -0.05, 0): it
// slides). At r = (0.5, 0, 0), u = (0, 0.5, 0) and De Saxce's u^ = (0.05, 0.5, 0); with rho = W_nn = 2,
// x = rho r - u^ = (0.95, -0.5, 0) lies outside the cone, whose projection has normal part
// (0.95 + 0.1 * 0.5) / 1.01 = 1/1.01 and tangential part 0.1/1.01 along -e_t: F = (1, 0, 0) - that
// = (0.01, 0.1, 0) / 1.01, |F| = 0.1 / sqrt(1.01), twice the rho = 1 map (the cone is a cone).
TEST(LocalProblem, PointResidualsAreTheNaturalMapInVelocityUnits) {
  LocalProblem p;
  p.W = {3, 3, {0, 1, 2, 3}, {0, 1, 2}, {2.0, 1.0, 1.0}};
  p.q = {-1.0, 0.5, 0.0};
  p.mu = {0.1};
  const std::vector<double> guess = {0.5, 0.0, 0.0};
  const std::vector<double> at_guess = point_residuals(p, guess, local_velocities(p, guess));
  ASSERT_EQ(at_guess.size(), 1U);
  EXPECT_NEAR(at_guess[0], 0.1 / std::sqrt(1.01), 1e-15);
  // |q| = sqrt(1.25): the FCLib error is the rho = 1 map over it, half the velocity-unit residual here.
  EXPECT_NEAR(fclib_error(p, guess, local_velocities(p, guess)) * std::sqrt(1.25), at_guess[0] / 2.0, 1e-15);
  const std::vector<double> solution = {0.5, -0.05, 0.0};
  EXPECT_NEAR(point_residuals(p, solution, local_velocities(p, solution))[0], 0.0, 1e-15);
}

TEST(LocalProblem, ShuffledOrderReachesTheSameTolerance) {
  const LocalProblem p = random_problem(10, 7);
  LocalProblemOptions options;
  options.tolerance = 1e-9;
  options.order = SweepOrder::shuffled;
  const LocalProblemSolution s = solve_local_problem(p, options);
  EXPECT_TRUE(s.converged);
  EXPECT_LE(s.error, 1e-9);
}

// A rank-deficient W = H^T H (3n local rows, fewer body coordinates), as for boxes resting on
// several contacts per face: the solution r is not unique and Gauss-Seidel crawls; the polish
// must still reach a tight tolerance, checked with the library-independent Alart-Curnier zero.
LocalProblem rank_deficient_problem(std::size_t n, int coordinates, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int m = static_cast<int>(3 * n);
  Eigen::MatrixXd H(coordinates, m);
  for (int i = 0; i < coordinates; ++i)
    for (int j = 0; j < m; ++j) H(i, j) = u(rng);
  const Eigen::MatrixXd W = H.transpose() * H;
  LocalProblem p;
  p.W.rows = p.W.columns = m;
  p.W.row_start.push_back(0);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) {
      p.W.column.push_back(j);
      p.W.value.push_back(W(i, j));
    }
    p.W.row_start.push_back(static_cast<int>(p.W.value.size()));
  }
  // q = H^T f with a compressive normal part so that a solution exists (u = H^T (H r + f)).
  Eigen::VectorXd f(coordinates);
  for (int i = 0; i < coordinates; ++i) f(i) = u(rng);
  const Eigen::VectorXd q = H.transpose() * f;
  for (int i = 0; i < m; ++i) p.q.push_back(q(i) - (i % 3 == 0 ? 1.0 : 0.0));
  for (std::size_t k = 0; k < n; ++k) p.mu.push_back(0.5);
  return p;
}

TEST(LocalProblem, AlartCurnierFunctionVanishesExactlyAtTheSolution) {
  const LocalProblem p = random_problem(8, 3);
  LocalProblemOptions options;
  options.tolerance = 1e-13;
  const LocalProblemSolution s = solve_local_problem(p, options);
  ASSERT_TRUE(s.converged);
  double norm = 0.0;
  for (double f : alart_curnier_function(p, s.r)) norm = std::max(norm, std::abs(f));
  EXPECT_LT(norm, 1e-11);
  // At r = 0 with a compressive q_n, F_n = rho q_n != 0 for some contact.
  double at_zero = 0.0;
  for (double f : alart_curnier_function(p, std::vector<double>(p.q.size(), 0.0)))
    at_zero = std::max(at_zero, std::abs(f));
  EXPECT_GT(at_zero, 1e-3);
}

// The sweeps alone do not reach 1e-10 within 60 sweeps on these problems (they need 92-169, or
// stall); the polish, which is then the only way to the tolerance within the budget, must get
// there. (Where the sweeps would get there in time, the polish is taken only if its Newton steps
// cost less than the sweeps left: solve_local_problem, polish_pays.)
TEST(LocalProblem, NewtonPolishSolvesRankDeficientProblemsWhereSweepsStall) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const LocalProblem p = rank_deficient_problem(10, 18, seed);
    LocalProblemOptions options;
    options.tolerance = 1e-10;
    options.max_iterations = 60;
    const LocalProblemSolution plain = solve_local_problem(p, options);
    EXPECT_FALSE(plain.converged) << "seed " << seed << ": the sweeps alone got there";
    options.polish = PolishMethod::newton;
    const LocalProblemSolution polished = solve_local_problem(p, options);
    EXPECT_TRUE(polished.converged) << "seed " << seed << " error " << polished.error;
    EXPECT_LE(fclib_error(p, polished.r, polished.u), 1e-10);
    EXPECT_GT(polished.newton_iterations, 0) << "seed " << seed;
  }
}

// Frictionless contacts, some of them separating: the polish takes the open contacts' and the
// tangential components outright (unit rows of the Alart-Curnier Jacobian) and factorises the
// closed contacts' normal rows only. From r = 0 it must reach 1e-12 in a few Newton steps with
// no tangential impulse and none on the separating contacts.
TEST(LocalProblem, NewtonPolishSolvesFrictionlessProblemsWithOpenContacts) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    LocalProblem p = rank_deficient_problem(12, 24, seed);
    std::fill(p.mu.begin(), p.mu.end(), 0.0);
    for (std::size_t k = 0; k < 3; ++k) p.q[3 * k] += 50.0;  // moving apart fast: open at the solution
    LocalProblemOptions options;
    options.tolerance = 1e-12;
    std::vector<double> r(p.q.size(), 0.0);
    std::vector<double> u = local_velocities(p, r);
    double error = fclib_error(p, r, u);
    const int steps = polish_solution(p, options, r, u, error);
    EXPECT_GT(steps, 0) << "seed " << seed;
    EXPECT_LE(steps, 12) << "seed " << seed;
    EXPECT_LE(error, 1e-12) << "seed " << seed;
    EXPECT_LE(fclib_error(p, r, u), 1e-12) << "seed " << seed;
    double largest_normal = 0.0;
    for (std::size_t k = 0; k < p.contact_count(); ++k) {
      largest_normal = std::max(largest_normal, r[3 * k]);
      EXPECT_EQ(r[3 * k + 1], 0.0) << "seed " << seed << " contact " << k;
      EXPECT_EQ(r[3 * k + 2], 0.0) << "seed " << seed << " contact " << k;
      if (k < 3) {
        EXPECT_EQ(r[3 * k], 0.0) << "seed " << seed << " separating contact " << k;
      }
    }
    EXPECT_GT(largest_normal, 0.1) << "seed " << seed << ": no contact pressed";
  }
}

TEST(LocalProblem, RejectsInconsistentSizes) {
  LocalProblem p = random_problem(2, 1);
  p.mu.push_back(0.1);
  EXPECT_THROW(solve_local_problem(p, {}), std::invalid_argument);
}

}  // namespace
}  // namespace rubble
