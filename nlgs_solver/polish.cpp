// The simulation's Newton polish (polish.hpp): W assembled in scaled impulses, then the
// file-backed problems' Levenberg-Marquardt polish (local_problem.cpp) from the sweeps' iterate.
#include "nlgs_solver/polish.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "nlgs_solver/coulomb.hpp"
#include "nlgs_solver/local_problem.hpp"

namespace rubble {
namespace {

/// The contacts' problem as explicit data for the Newton polish, in scaled impulses
/// r~_k = W_kk,nn r_k (velocity units), so that the polish's error measure (natural map with
/// rho = 1 on r~, u) is the sweeps' criterion (natural map with rho = W_nn on r, u):
/// u = W~ r~ + q with W~_kl = W_kl / d_l, and W_kl = R_k^T (sum over shared moving bodies of
/// s_k s_l K(arm_k, arm_l)) R_l, K(x, y) = m^-1 I - [x] I^-1 [y], s = +1 on the b side, -1 on a.
struct ScaledProblem {
  LocalProblem problem;                   ///< W~, q, mu
  std::vector<double> normal_compliance;  ///< d_k = W_kk,nn
};

/// The polish's view of the compact problem: its unknown k is contact k of the ContactList, that
/// is point `point[k]` of the copy.
struct PolishView {
  const CompactProblem& compact;
  std::vector<std::size_t> point;  ///< the inverse of the plan's order
  /// Contact k's point.
  const CompactProblem::Point& at(std::size_t k) const { return compact.points[point[k]]; }
};

/// Row k of W~ (before the scaling by the frames and d_l): (l, sum of s_k s_l K) for every
/// contact l sharing a moving body with k, sorted by l with the two bodies' terms merged.
/// `of_body`: the contacts of each moving body (local body index), in increasing order.
std::vector<std::pair<std::size_t, Mat3>> coupled_blocks(const PolishView& view,
                                                         const std::vector<std::vector<std::size_t>>& of_body,
                                                         std::size_t k) {
  auto side = [](const CompactProblem::Point& c, std::uint32_t body, Vec3& arm) {
    if (c.b == body) {
      arm = c.arm_b;
      return 1.0;
    }
    arm = c.arm_a;
    return -1.0;
  };
  const CompactProblem::Point& ck = view.at(k);
  std::vector<std::pair<std::size_t, Mat3>> row;
  for (const std::uint32_t body : {ck.a, ck.b}) {
    const CompactProblem::Body& moving = view.compact.bodies[body];
    if (moving.inverse_mass == 0.0) continue;  // Model::is_fixed
    Vec3 arm_k, arm_l;
    const double sk = side(ck, body, arm_k);
    for (const std::size_t l : of_body[body]) {
      const double sl = side(view.at(l), body, arm_l);
      const Mat3 compliance =
          moving.inverse_mass * Mat3::Identity() - skew(arm_k) * moving.inverse_inertia * skew(arm_l);
      row.emplace_back(l, sk * sl * compliance);
    }
  }
  std::sort(row.begin(), row.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<std::pair<std::size_t, Mat3>> merged;
  for (const auto& [l, m] : row) {
    if (!merged.empty() && merged.back().first == l)
      merged.back().second += m;
    else
      merged.emplace_back(l, m);
  }
  return merged;
}

/// Which unknowns the assembled problem is in: the polish's scaled impulses r~ = d r, or the
/// impulses r themselves (every d taken as 1: W is then the symmetric Delassus operator).
enum class Unknowns { scaled_impulses, impulses };

/// W~, d and mu of the view's contacts (ScaledProblem); q is left to the caller.
ScaledProblem assemble_problem(const PolishView& view, Unknowns unknowns) {
  const bool scaled = unknowns == Unknowns::scaled_impulses;
  const std::size_t n = view.point.size();
  ScaledProblem out;
  out.normal_compliance.resize(n);
  for (std::size_t k = 0; k < n; ++k) out.normal_compliance[k] = scaled ? view.at(k).delassus(0, 0) : 1.0;
  // Contacts of each moving body.
  std::vector<std::vector<std::size_t>> of_body(view.compact.bodies.size());
  for (std::size_t k = 0; k < n; ++k) {
    for (const std::uint32_t body : {view.at(k).a, view.at(k).b}) {
      if (view.compact.bodies[body].inverse_mass != 0.0) of_body[body].push_back(k);
    }
  }
  SparseMatrix& W = out.problem.W;
  W.rows = W.columns = static_cast<int>(3 * n);
  W.row_start.assign(1, 0);
  for (std::size_t k = 0; k < n; ++k) {
    std::vector<std::pair<std::size_t, Mat3>> blocks = coupled_blocks(view, of_body, k);
    for (auto& [l, m] : blocks) m = view.at(k).frame.transpose() * m * view.at(l).frame / out.normal_compliance[l];
    for (int i = 0; i < 3; ++i) {
      for (const auto& [l, m] : blocks) {
        for (int j = 0; j < 3; ++j) {
          W.column.push_back(static_cast<int>(3 * l) + j);
          W.value.push_back(m(i, j));
        }
      }
      W.row_start.push_back(static_cast<int>(W.column.size()));
    }
  }
  out.problem.mu.resize(n);
  for (std::size_t k = 0; k < n; ++k) out.problem.mu[k] = view.at(k).friction_coefficient;
  return out;
}

/// q = u - W~ r~: the local velocities without any impulse.
std::vector<double> free_velocities(const SparseMatrix& W, const std::vector<double>& r, const std::vector<double>& u) {
  std::vector<double> q = u;
  for (std::size_t row = 0; row < static_cast<std::size_t>(W.rows); ++row) {
    for (auto e = static_cast<std::size_t>(W.row_start[row]); e < static_cast<std::size_t>(W.row_start[row + 1]); ++e) {
      q[row] -= W.value[e] * r[static_cast<std::size_t>(W.column[e])];
    }
  }
  return q;
}

}  // namespace

LocalProblem explicit_contact_problem(const CompactProblem& compact, std::span<const std::size_t> order) {
  PolishView view{compact, std::vector<std::size_t>(order.size())};
  for (std::size_t p = 0; p < order.size(); ++p) view.point[order[p]] = p;
  LocalProblem problem = assemble_problem(view, Unknowns::impulses).problem;
  problem.q.resize(3 * view.point.size());
  for (std::size_t k = 0; k < view.point.size(); ++k) {
    const Vec3 u = compact.local_velocity(view.point[k]);  // the free velocities: no impulse applied yet
    for (int i = 0; i < 3; ++i) problem.q[3 * k + static_cast<std::size_t>(i)] = u[i];
  }
  return problem;
}

namespace {

/// Polishes the view's contacts from the current iterate (the others' impulses held fixed: their
/// part of every velocity is in q), at most `iterations` Levenberg-Marquardt steps, until the
/// FCLib measure of the view's problem is at most tolerance(q). When the impulses projected on their
/// cones lower the error, they are applied to the bodies.
template <class Tolerance>
PolishOutcome polish_view(CompactProblem& compact, const PolishView& view, int iterations, Tolerance tolerance) {
  const std::size_t n = view.point.size();
  ScaledProblem scaled = assemble_problem(view, Unknowns::scaled_impulses);
  LocalProblem& problem = scaled.problem;
  std::vector<double> r(3 * n), u(3 * n);
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3 velocity = compact.local_velocity(view.point[k]);
    for (int i = 0; i < 3; ++i) {
      r[3 * k + static_cast<std::size_t>(i)] = scaled.normal_compliance[k] * view.at(k).impulse[i];
      u[3 * k + static_cast<std::size_t>(i)] = velocity[i];
    }
  }
  problem.q = free_velocities(problem.W, r, u);
  LocalProblemOptions polish;
  polish.tolerance = tolerance(problem.q);
  polish.polish_iterations = iterations;
  double error = fclib_error(problem, r, u);
  const double before = error;
  PolishOutcome result;
  result.newton_steps = polish_solution(problem, polish, r, u, error);
  if (error < before) {
    // An attempt stopped at its step cap may sit well outside the cones: what is applied is the
    // projection, so its error is what must be lower (and what the convergence test reads).
    for (std::size_t k = 0; k < n; ++k) {
      const Vec3 projected = project_onto_coulomb_cone(Vec3(r[3 * k], r[3 * k + 1], r[3 * k + 2]), problem.mu[k]);
      for (int i = 0; i < 3; ++i) r[3 * k + static_cast<std::size_t>(i)] = projected[i];
    }
    u = local_velocities(problem, r);
    error = fclib_error(problem, r, u);
  }
  if (error < before) {
    for (std::size_t k = 0; k < n; ++k) {
      // r~ is on its cone already; the division by d may round it a hair outside.
      const std::size_t p = view.point[k];
      const Vec3 next =
          project_onto_coulomb_cone(Vec3(r[3 * k], r[3 * k + 1], r[3 * k + 2]) / scaled.normal_compliance[k],
                                    compact.points[p].friction_coefficient);
      const Vec3 delta = next - compact.points[p].impulse;
      compact.points[p].impulse = next;
      compact.apply_impulse_change(p, delta);
    }
  }
  result.converged = error <= polish.tolerance;
  return result;
}

}  // namespace

PolishOutcome polish_compact_problem(CompactProblem& compact, std::span<const std::size_t> order, int iterations,
                                     double tolerance) {
  PolishView view{compact, std::vector<std::size_t>(order.size())};
  for (std::size_t p = 0; p < order.size(); ++p) view.point[order[p]] = p;
  return polish_view(compact, view, iterations, [tolerance](const std::vector<double>&) { return tolerance; });
}

ClusterPolishOutcome polish_stalled_cluster(CompactProblem& compact, const ClusterPolishOptions& options) {
  ClusterPolishOutcome outcome;
  const std::size_t count = compact.size();
  // Each point's share of the sweeps' residual ||F||^2, on the current iterate.
  std::vector<double> residual(count);
  double total = 0.0;
  for (std::size_t p = 0; p < count; ++p) total += residual[p] = compact.residual_squared(p);
  if (!(total > 0.0)) return outcome;
  // The fewest points that hold the given share of it (largest first, ties by position).
  std::vector<std::size_t> ranked(count);
  for (std::size_t p = 0; p < count; ++p) ranked[p] = p;
  const std::size_t seeds_at_most = std::min(options.max_seed_points, count);
  std::partial_sort(
      ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(seeds_at_most), ranked.end(),
      [&](std::size_t x, std::size_t y) { return residual[x] > residual[y] || (residual[x] == residual[y] && x < y); });
  double held = 0.0;
  std::size_t seeds = 0;
  while (seeds < seeds_at_most && held < options.residual_share * total) held += residual[ranked[seeds++]];
  if (held < options.residual_share * total) return outcome;  // spread out: not a stalled cluster
  // Their moving bodies; every point between those bodies (or between one and a wall) is polished,
  // and every point touching one of them sees its velocity change.
  std::vector<char> in_cluster(compact.bodies.size(), 0);
  std::vector<std::uint32_t> bodies;
  for (std::size_t i = 0; i < seeds; ++i) {
    const CompactProblem::Point& c = compact.points[ranked[i]];
    for (const std::uint32_t body : {c.a, c.b}) {
      if (compact.bodies[body].inverse_mass != 0.0 && !in_cluster[body]) {
        in_cluster[body] = 1;
        bodies.push_back(body);
      }
    }
  }
  PolishView view{compact, {}};
  std::vector<std::size_t> touched;
  for (std::size_t p = 0; p < count; ++p) {
    const CompactProblem::Point& c = compact.points[p];
    const bool a_fixed = compact.bodies[c.a].inverse_mass == 0.0, b_fixed = compact.bodies[c.b].inverse_mass == 0.0;
    if (!in_cluster[c.a] && !in_cluster[c.b]) continue;
    touched.push_back(p);
    if ((in_cluster[c.a] || a_fixed) && (in_cluster[c.b] || b_fixed)) view.point.push_back(p);
  }
  if (view.point.size() > options.max_points) return outcome;
  // Kept to undo the polish: only the cluster's bodies and points change (walls are never written).
  std::vector<CompactProblem::Body> saved_bodies;
  saved_bodies.reserve(bodies.size());
  for (const std::uint32_t body : bodies) saved_bodies.push_back(compact.bodies[body]);
  std::vector<Vec3> saved_impulses;
  saved_impulses.reserve(view.point.size());
  for (const std::size_t p : view.point) saved_impulses.push_back(compact.points[p].impulse);
  const double target = options.residual_target;
  const PolishOutcome polished = polish_view(compact, view, options.iterations, [target](const std::vector<double>& q) {
    double q_squared = 0.0;
    for (const double x : q) q_squared += x * x;
    return q_squared > 0.0 ? target / std::sqrt(q_squared) : 0.0;
  });
  outcome.newton_steps = polished.newton_steps;
  // The block's error fell; the whole residual must too (the points around the cluster see its
  // new velocities), else the sweeps' iterate is put back as it was, to the bit.
  double before = 0.0, after = 0.0;
  for (const std::size_t p : touched) {
    before += residual[p];
    after += compact.residual_squared(p);
  }
  if (!(after < before)) {
    for (std::size_t i = 0; i < bodies.size(); ++i) compact.bodies[bodies[i]] = saved_bodies[i];
    for (std::size_t i = 0; i < view.point.size(); ++i) compact.points[view.point[i]].impulse = saved_impulses[i];
    return outcome;
  }
  // The polish may have loaded points a sweep left open: their notes no longer hold.
  for (const std::size_t p : view.point) compact.forget_open_point(p);
  outcome.points = view.point.size();
  return outcome;
}

}  // namespace rubble
