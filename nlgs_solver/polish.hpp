#pragma once
// The simulation's Newton polish (nlgs_solver/README.md, "The simulation's Newton polish"): when
// the sweeps crawl (hyperstatic stacks, rank-deficient W), the step's W is assembled explicitly
// and the file-backed problems' Levenberg-Marquardt polish (local_problem.hpp) is run from the
// sweeps' iterate.
#include <cstddef>
#include <span>

#include "nlgs_solver/compact_problem.hpp"
#include "nlgs_solver/local_problem.hpp"

namespace rubble {

/// What one polish did.
struct PolishOutcome {
  int newton_steps = 0;    ///< Levenberg-Marquardt steps taken
  bool converged = false;  ///< the tolerance was met
};

/// One Newton polish of the compact problem's current impulses (see SolverOptions::polish_after),
/// at most `iterations` steps. When it lowers the error, the impulses and the bodies' velocities
/// hold the polished solution. `tolerance` is on the FCLib measure of the whole problem
/// (||F|| / ||q|| over every contact, the impulses scaled by W_nn). `order` is the plan's order
/// (point p is contact order[p]): the polish numbers its unknowns in the ContactList's order, not
/// the sweeps', because that order fixes the rounding of the factorisation and of the velocity
/// updates, and the polish computed in it before it moved onto the compact copy (same results to
/// the bit).
PolishOutcome polish_compact_problem(CompactProblem& compact, std::span<const std::size_t> order, int iterations,
                                     double tolerance);

/// The contact problem of a compact copy whose velocities are still the free velocities (no
/// impulse applied) as explicit data: u = W r + q with W the Delassus operator in impulses (N s,
/// symmetric), q the points' local velocities without impulse (m/s, the normal target velocity
/// folded in), mu; unknown k is contact k of the ContactList (`order` as for the polish). Plain
/// Signorini-Coulomb-Newton laws only (the caller checks). For SolverOptions::problem_observer.
LocalProblem explicit_contact_problem(const CompactProblem& compact, std::span<const std::size_t> order);

}  // namespace rubble
