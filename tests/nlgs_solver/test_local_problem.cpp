// The file-backed (W, q, mu) problem: solved by the simulation's sweep to the FCLib error.
#include <gtest/gtest.h>

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

TEST(LocalProblem, ShuffledOrderReachesTheSameTolerance) {
  const LocalProblem p = random_problem(10, 7);
  LocalProblemOptions options;
  options.tolerance = 1e-9;
  options.order = SweepOrder::shuffled;
  const LocalProblemSolution s = solve_local_problem(p, options);
  EXPECT_TRUE(s.converged);
  EXPECT_LE(s.error, 1e-9);
}

TEST(LocalProblem, RejectsInconsistentSizes) {
  LocalProblem p = random_problem(2, 1);
  p.mu.push_back(0.1);
  EXPECT_THROW(solve_local_problem(p, {}), std::invalid_argument);
}

}  // namespace
}  // namespace rubble
