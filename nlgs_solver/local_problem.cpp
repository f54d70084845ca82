#include "nlgs_solver/local_problem.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

#include "nlgs_solver/coulomb.hpp"
#include "nlgs_solver/sweep.hpp"

namespace rubble {
namespace {

/// u = W r + q.
std::vector<double> velocities(const LocalProblem& p, const std::vector<double>& r) {
  std::vector<double> u(p.q);
  for (int row = 0; row < p.W.rows; ++row) {
    double sum = 0.0;
    for (int k = p.W.row_start[static_cast<std::size_t>(row)]; k < p.W.row_start[static_cast<std::size_t>(row) + 1]; ++k) {
      sum += p.W.value[static_cast<std::size_t>(k)] * r[static_cast<std::size_t>(p.W.column[static_cast<std::size_t>(k)])];
    }
    u[static_cast<std::size_t>(row)] += sum;
  }
  return u;
}

/// W explicit: u_k is recomputed from its three rows, so applying a change needs no work.
struct ExplicitProblem {
  const LocalProblem& p;
  std::vector<Mat3> diagonal_blocks;
  std::vector<Vec3> r;

  std::size_t size() const { return p.contact_count(); }
  const Mat3& delassus(std::size_t k) const { return diagonal_blocks[k]; }
  double friction_coefficient(std::size_t k) const { return p.mu[k]; }
  Vec3& impulse(std::size_t k) { return r[k]; }
  Vec3 local_velocity(std::size_t k) const {
    Vec3 u;
    for (int i = 0; i < 3; ++i) {
      const std::size_t row = 3 * k + static_cast<std::size_t>(i);
      double sum = p.q[row];
      for (int e = p.W.row_start[row]; e < p.W.row_start[row + 1]; ++e) {
        const auto column = static_cast<std::size_t>(p.W.column[static_cast<std::size_t>(e)]);
        sum += p.W.value[static_cast<std::size_t>(e)] * r[column / 3][static_cast<Eigen::Index>(column % 3)];
      }
      u[i] = sum;
    }
    return u;
  }
  void apply_impulse_change(std::size_t, const Vec3&) {}
};

}  // namespace

double fclib_error(const LocalProblem& problem, const std::vector<double>& r, const std::vector<double>& u) {
  double f2 = 0.0, q2 = 0.0;
  for (std::size_t k = 0; k < problem.contact_count(); ++k) {
    const Vec3 rk(r[3 * k], r[3 * k + 1], r[3 * k + 2]);
    const Vec3 uk(u[3 * k], u[3 * k + 1], u[3 * k + 2]);
    f2 += natural_map(rk, uk, problem.mu[k]).squaredNorm();
  }
  for (double x : problem.q) q2 += x * x;
  const double q_norm = std::sqrt(q2);
  return std::sqrt(f2) / (q_norm > 0.0 ? q_norm : 1.0);
}

LocalProblemSolution solve_local_problem(const LocalProblem& problem, const LocalProblemOptions& options) {
  const std::size_t n = problem.contact_count();
  if (problem.W.rows != static_cast<int>(3 * n) || problem.q.size() != 3 * n ||
      problem.W.row_start.size() != 3 * n + 1) {
    throw std::invalid_argument("local problem: W, q and mu sizes disagree");
  }
  ExplicitProblem explicit_problem{problem, std::vector<Mat3>(n, Mat3::Zero()), std::vector<Vec3>(n, Vec3::Zero())};
  for (std::size_t row = 0; row < 3 * n; ++row) {
    for (int e = problem.W.row_start[row]; e < problem.W.row_start[row + 1]; ++e) {
      const auto column = static_cast<std::size_t>(problem.W.column[static_cast<std::size_t>(e)]);
      if (column / 3 == row / 3) {
        explicit_problem.diagonal_blocks[row / 3](static_cast<Eigen::Index>(row % 3), static_cast<Eigen::Index>(column % 3)) =
            problem.W.value[static_cast<std::size_t>(e)];
      }
    }
  }
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  if (options.order == SweepOrder::shuffled) {
    std::mt19937_64 generator(options.seed);
    std::shuffle(order.begin(), order.end(), generator);
  }

  LocalProblemSolution solution;
  solution.r.assign(3 * n, 0.0);
  auto flatten = [&] {
    for (std::size_t k = 0; k < n; ++k)
      for (int i = 0; i < 3; ++i) solution.r[3 * k + static_cast<std::size_t>(i)] = explicit_problem.r[k][i];
  };
  for (solution.iterations = 1; solution.iterations <= options.max_iterations; ++solution.iterations) {
    nlgs_sweep(explicit_problem, order, options.relaxation);
    flatten();
    solution.u = velocities(problem, solution.r);
    solution.error = fclib_error(problem, solution.r, solution.u);
    if (solution.error <= options.tolerance) {
      solution.converged = true;
      break;
    }
  }
  solution.iterations = std::min(solution.iterations, options.max_iterations);
  if (n == 0) {
    solution.u = problem.q;
    solution.converged = true;
  }
  return solution;
}

}  // namespace rubble
