#pragma once
// The simulation's Newton polish (nlgs_solver/README.md, "The simulation's Newton polish"): when
// the sweeps crawl (hyperstatic stacks, rank-deficient W), the step's W is assembled explicitly
// and the file-backed problems' Levenberg-Marquardt polish (local_problem.hpp) is run from the
// sweeps' iterate.
#include <cstddef>
#include <vector>

#include "core/model.hpp"
#include "nlgs_solver/nlgs.hpp"

namespace rubble {

/// The simulation's contact problem on the ContactList: W = H^T M^-1 H is never assembled; u_k is
/// read off the two bodies' current velocities and an impulse change is applied to them at once.
struct BodyCoupledProblem {
  const Model& model;                             ///< inverse masses, walls
  ContactList& contacts;                          ///< frames, arms, Delassus blocks, impulses
  BodyVelocities& velocity;                       ///< the bodies' current velocities
  const std::vector<Mat3>& inverse_inertia_world;  ///< per body, at the start of the step

  /// Number of contacts.
  std::size_t size() const { return contacts.size(); }
  /// W_kk of contact k.
  const Mat3& delassus(std::size_t k) const { return contacts[k].delassus; }
  /// mu of contact k.
  double friction_coefficient(std::size_t k) const { return contacts[k].friction_coefficient; }
  /// r_k of contact k.
  Vec3& impulse(std::size_t k) { return contacts[k].impulse; }

  /// u = R^T (v_b + w_b x arm_b - v_a - w_a x arm_a) - b e_n: the target velocity b is folded in,
  /// so the law reads 0 <= r_n _|_ u_n >= 0.
  Vec3 local_velocity(std::size_t k) const {
    const Contact& c = contacts[k];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    const Vec3 relative = velocity.linear[b] + velocity.angular[b].cross(c.arm_b) - velocity.linear[a] -
                          velocity.angular[a].cross(c.arm_a);
    Vec3 u = c.frame.transpose() * relative;
    u.x() -= c.normal_velocity_target;
    return u;
  }

  /// Applies the change `delta` of contact k's impulse to its two bodies (walls are never written).
  void apply_impulse_change(std::size_t k, const Vec3& delta) {
    const Contact& c = contacts[k];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    const Vec3 p = c.frame * delta;  // world impulse on b; -p on a
    if (!model.is_fixed(b)) {
      velocity.linear[b] += model.inverse_mass[b] * p;
      velocity.angular[b] += inverse_inertia_world[b] * c.arm_b.cross(p);
    }
    if (!model.is_fixed(a)) {
      velocity.linear[a] -= model.inverse_mass[a] * p;
      velocity.angular[a] -= inverse_inertia_world[a] * c.arm_a.cross(p);
    }
  }
};

/// What one polish did.
struct PolishResult {
  int newton_steps = 0;    ///< Levenberg-Marquardt steps taken
  bool converged = false;  ///< the tolerance was met
};

/// One Newton polish of the current impulses (see SolverOptions::polish_after), at most
/// `iterations` steps. When it lowers the error, the impulses and the bodies' velocities hold the
/// polished solution. `tolerance` is on the FCLib measure of the whole problem (||F|| / ||q|| over
/// every contact, the impulses scaled by W_nn).
PolishResult polish_contacts(const Model& model, BodyCoupledProblem& coupled, int iterations, double tolerance);

}  // namespace rubble
