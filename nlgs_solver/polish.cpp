// The simulation's Newton polish (polish.hpp): W assembled in scaled impulses, then the
// file-backed problems' Levenberg-Marquardt polish (local_problem.cpp) from the sweeps' iterate.
#include "nlgs_solver/polish.hpp"

#include <algorithm>
#include <utility>

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

/// Row k of W~ (before the scaling by the frames and d_l): (l, sum of s_k s_l K) for every
/// contact l sharing a moving body with k, sorted by l with the two bodies' terms merged.
std::vector<std::pair<std::size_t, Mat3>> coupled_blocks(const Model& model, const BodyCoupledProblem& coupled,
                                                         const std::vector<std::vector<std::size_t>>& of_body,
                                                         std::size_t k) {
  const ContactList& contacts = coupled.contacts;
  auto side = [&](const Contact& c, std::size_t body, Vec3& arm) {
    if (c.id.body_b == body) {
      arm = c.arm_b;
      return 1.0;
    }
    arm = c.arm_a;
    return -1.0;
  };
  const Contact& ck = contacts[k];
  std::vector<std::pair<std::size_t, Mat3>> row;
  for (const std::size_t body : {ck.id.body_a, ck.id.body_b}) {
    if (model.is_fixed(body)) continue;
    Vec3 arm_k, arm_l;
    const double sk = side(ck, body, arm_k);
    const Mat3& inverse_inertia = coupled.inverse_inertia_world[body];
    for (const std::size_t l : of_body[body]) {
      const double sl = side(contacts[l], body, arm_l);
      const Mat3 compliance = model.inverse_mass[body] * Mat3::Identity() - skew(arm_k) * inverse_inertia * skew(arm_l);
      row.emplace_back(l, sk * sl * compliance);
    }
  }
  std::sort(row.begin(), row.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<std::pair<std::size_t, Mat3>> merged;
  for (const auto& [l, m] : row) {
    if (!merged.empty() && merged.back().first == l) merged.back().second += m;
    else merged.emplace_back(l, m);
  }
  return merged;
}

ScaledProblem assemble_scaled_problem(const Model& model, const BodyCoupledProblem& coupled) {
  const ContactList& contacts = coupled.contacts;
  const std::size_t n = contacts.size();
  ScaledProblem out;
  out.normal_compliance.resize(n);
  for (std::size_t k = 0; k < n; ++k) out.normal_compliance[k] = contacts[k].delassus(0, 0);
  // Contacts of each moving body.
  std::vector<std::vector<std::size_t>> of_body(model.body_count());
  for (std::size_t k = 0; k < n; ++k) {
    if (!model.is_fixed(contacts[k].id.body_a)) of_body[contacts[k].id.body_a].push_back(k);
    if (!model.is_fixed(contacts[k].id.body_b)) of_body[contacts[k].id.body_b].push_back(k);
  }
  SparseMatrix& W = out.problem.W;
  W.rows = W.columns = static_cast<int>(3 * n);
  W.row_start.assign(1, 0);
  for (std::size_t k = 0; k < n; ++k) {
    std::vector<std::pair<std::size_t, Mat3>> blocks = coupled_blocks(model, coupled, of_body, k);
    for (auto& [l, m] : blocks) m = contacts[k].frame.transpose() * m * contacts[l].frame / out.normal_compliance[l];
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
  for (std::size_t k = 0; k < n; ++k) out.problem.mu[k] = contacts[k].friction_coefficient;
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

PolishResult polish_contacts(const Model& model, BodyCoupledProblem& coupled, int iterations, double tolerance) {
  ContactList& contacts = coupled.contacts;
  const std::size_t n = contacts.size();
  ScaledProblem scaled = assemble_scaled_problem(model, coupled);
  LocalProblem& problem = scaled.problem;
  std::vector<double> r(3 * n), u(3 * n);
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3 velocity = coupled.local_velocity(k);
    for (int i = 0; i < 3; ++i) {
      r[3 * k + static_cast<std::size_t>(i)] = scaled.normal_compliance[k] * contacts[k].impulse[i];
      u[3 * k + static_cast<std::size_t>(i)] = velocity[i];
    }
  }
  problem.q = free_velocities(problem.W, r, u);
  LocalProblemOptions polish;
  polish.tolerance = tolerance;
  polish.polish_iterations = iterations;
  double error = fclib_error(problem, r, u);
  const double before = error;
  PolishResult result;
  result.newton_steps = polish_solution(problem, polish, r, u, error);
  if (error < before) {
    for (std::size_t k = 0; k < n; ++k) {
      // Newton's iterate may sit a rounding error outside the cone; the impulse must not.
      const Vec3 next = project_onto_coulomb_cone(Vec3(r[3 * k], r[3 * k + 1], r[3 * k + 2]) / scaled.normal_compliance[k],
                                                  contacts[k].friction_coefficient);
      const Vec3 delta = next - contacts[k].impulse;
      contacts[k].impulse = next;
      coupled.apply_impulse_change(k, delta);
    }
  }
  result.converged = error <= tolerance;
  return result;
}

}  // namespace rubble
