#pragma once
// The preparation of a step's contacts (prepare.cpp, LMGC90's "prep_nlgs"): arms, Delassus
// blocks, laws, normal target velocities and cohesive impulses. `prepare_contacts` itself is
// declared with the rest of the solver's interface in nlgs.hpp; this header holds what the
// preparation shares with the other parts of the solver.
#include <cstddef>
#include <vector>

#include "core/contact.hpp"
#include "core/model.hpp"

namespace rubble {

/// Reduced radius r_eff = r_a r_b / (r_a + r_b) of a contact's bodies from their volume-equivalent
/// radii (a sphere's own radius), a grain's own radius against a wall: the radius the cohesive
/// pull-off force (prepare.cpp) and the rolling and twisting bounds (compact_problem.cpp) scale
/// with, so that both use one definition.
double reduced_radius(const Model& model, std::size_t a, std::size_t b);

/// Velocity of body b's material point at contact c relative to body a's, world frame, for the
/// bodies' velocities `linear` and `angular`: v_b + w_b x arm_b - v_a - w_a x arm_a. The state's
/// velocities give the pre-impact velocity of the restitution laws, the free ones the prediction.
inline Vec3 contact_relative_velocity(const Contact& c, const std::vector<Vec3>& linear,
                                      const std::vector<Vec3>& angular) {
  const std::size_t a = c.id.body_a, b = c.id.body_b;
  return linear[b] + angular[b].cross(c.arm_b) - linear[a] - angular[a].cross(c.arm_a);
}

}  // namespace rubble
