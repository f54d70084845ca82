#pragma once
// One nonlinear Gauss-Seidel sweep, shared by the simulation (W implicit through the bodies'
// velocities) and by file-backed problems (W explicit, e.g. FCLib). A Problem provides:
//   std::size_t size() const;                     number of contacts
//   Vec3 local_velocity(std::size_t k) const;     u_k = (W r + q)_k for the current impulses
//   const Mat3& delassus(std::size_t k) const;    W_kk
//   const Mat3& delassus_inverse(std::size_t k) const;  W_kk^-1 (computed once, as W_kk.inverse())
//   double friction_coefficient(std::size_t k) const;
//   Vec3& impulse(std::size_t k);                 r_k
//   void apply_impulse_change(std::size_t k, const Vec3& delta);  keeps later u_j consistent
// and optionally
//   void resist_rotation(std::size_t k, SweepResult& sums);  the contact's rolling and twisting
//                                                            block, solved right after its force
//   bool stays_open(std::size_t k) const;  and
//   void note_visit(std::size_t k, const Vec3& u, const Vec3& free_velocity, const Vec3& next);
//       skip points left open that cannot have closed (CompactProblem; nlgs_solver/README.md,
//       "Open contacts skipped")
//   void prefetch_point(std::size_t k) const;  and
//   void prefetch_bodies(std::size_t k) const;
//       request a later point's data and its bodies ahead of its visit (CompactProblem)
#include <cmath>
#include <cstddef>
#include <span>

#include "nlgs_solver/coulomb.hpp"
#include "nlgs_solver/local_solver.hpp"

namespace rubble {

/// Sums over one sweep, for the convergence test.
struct SweepResult {
  double residual_squared = 0.0;  ///< sum over contacts of ||F_k||^2 (natural map, velocity units)
  double impulse_squared = 0.0;   ///< sum over contacts of ||W_nn,k r_k||^2 after the update (velocity units)
  std::size_t passed_by = 0;      ///< open points not visited (CompactProblem::stays_open)
};

/// Sweeps the contacts in `order`: each local problem is solved exactly with the others frozen
/// (Jean 1999), relaxed by omega. The natural map of contact k is taken just before its update,
/// on the current iterate, so the convergence test costs no extra pass over the contacts.
template <class Problem>
SweepResult nlgs_sweep(Problem& problem, std::span<const std::size_t> order, double relaxation) {
  SweepResult result;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const std::size_t k = order[i];
    // Past ~10^4 spheres the compact copy (312 bytes a point) leaves the cache and each visit
    // waited on memory for its point, then for its bodies: ask for them a few points ahead
    // (bench/RESULTS.md, "Prefetching in the sweeps"). The bodies' request reads the point's body
    // indices, so it trails the point's request.
    if constexpr (requires { problem.prefetch_point(k); }) {
      constexpr std::size_t point_lead = 8, bodies_lead = 4;
      if (i + point_lead < order.size()) problem.prefetch_point(order[i + point_lead]);
      if (i + bodies_lead < order.size()) problem.prefetch_bodies(order[i + bodies_lead]);
    }
    // A point left open whose bodies have not moved enough to close it: its visit would return
    // r = 0 again and add 0 to both sums (CompactProblem::stays_open).
    if constexpr (requires { problem.stays_open(k); }) {
      if (problem.stays_open(k)) {
        ++result.passed_by;
        continue;
      }
    }
    const Mat3& W = problem.delassus(k);
    const double mu = problem.friction_coefficient(k);
    Vec3& r = problem.impulse(k);
    const Vec3 u = problem.local_velocity(k);
    // rho = W_nn puts the residual in velocity units, independent of the mass scale.
    result.residual_squared += natural_map(r, u, mu, W(0, 0)).squaredNorm();
    const Vec3 free_velocity = u - W * r;  // what u would be without this contact's impulse
    const LocalUpdate update =
        relaxed_local_update(W, problem.delassus_inverse(k), r, u, free_velocity, mu, relaxation);
    r = update.impulse;
    result.impulse_squared += (W(0, 0) * update.impulse).squaredNorm();
    problem.apply_impulse_change(k, update.change);
    if constexpr (requires { problem.note_visit(k, u, free_velocity, update.impulse); }) {
      problem.note_visit(k, u, free_velocity, update.impulse);
    }
    if constexpr (requires { problem.resist_rotation(k, result); }) problem.resist_rotation(k, result);
  }
  return result;
}

}  // namespace rubble
