#pragma once
// The preparation of a step's contacts (prepare.cpp, LMGC90's "prep_nlgs"): arms, Delassus
// blocks, laws, normal target velocities and cohesive impulses. `prepare_contacts` itself is
// declared with the rest of the solver's interface in nlgs.hpp; this header holds what the
// preparation shares with the other parts of the solver.
#include <cstddef>

#include "core/model.hpp"

namespace rubble {

/// Reduced radius r_eff = r_a r_b / (r_a + r_b) of a contact's bodies from their volume-equivalent
/// radii (a sphere's own radius), a grain's own radius against a wall: the radius the cohesive
/// pull-off force (prepare.cpp) and the rolling and twisting bounds (compact_problem.cpp) scale
/// with, so that both use one definition.
double reduced_radius(const Model& model, std::size_t a, std::size_t b);

}  // namespace rubble
