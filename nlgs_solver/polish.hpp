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
/// hold the polished solution (projected on the cones, whose error is the one compared).
/// `tolerance` is on the FCLib measure of the whole problem (||F|| / ||q|| over every contact, the
/// impulses scaled by W_nn). `order` is the plan's order
/// (point p is contact order[p]): the polish numbers its unknowns in the ContactList's order, not
/// the sweeps', because that order fixes the rounding of the factorisation and of the velocity
/// updates, and the polish computed in it before it moved onto the compact copy (same results to
/// the bit).
PolishOutcome polish_compact_problem(CompactProblem& compact, std::span<const std::size_t> order, int iterations,
                                     double tolerance);

/// Limits of the stalled cluster's polish (polish_stalled_cluster).
struct ClusterPolishOptions {
  double residual_share = 0.99;      ///< the cluster's seeds hold this share of ||F||^2
  std::size_t max_seed_points = 64;  ///< more seeds than this: the residual is spread out, no polish
  std::size_t max_points = 256;      ///< more points between the seeds' bodies than this: no polish
  int iterations = 20;               ///< Levenberg-Marquardt steps at most
  double residual_target = 0.0;      ///< ||F|| of the cluster's points to reach, velocity units (the sweeps' measure)
};

/// What a cluster polish did.
struct ClusterPolishOutcome {
  /// Points polished and kept (0: no small cluster held the residual, or the polish was undone).
  std::size_t points = 0;
  int newton_steps = 0;  ///< Levenberg-Marquardt steps taken
};

/// A block Gauss-Seidel step on the points that hold the sweeps' residual, for a problem too large
/// for polish_compact_problem (nlgs_solver/README.md, "The stalled cluster's polish"): when at most
/// `max_seed_points` points hold `residual_share` of ||F||^2, every point between their moving
/// bodies (or between one and a wall) is polished by Newton steps with every other impulse held
/// fixed. The result, projected on the cones, is kept when it lowers both that block's error and
/// the residual of every point touching its grains; otherwise the iterate is restored to the bit.
/// Serial and in the plan's order: the same result for any thread count.
ClusterPolishOutcome polish_stalled_cluster(CompactProblem& compact, const ClusterPolishOptions& options);

/// The contact problem of a compact copy whose velocities are still the free velocities (no
/// impulse applied) as explicit data: u = W r + q with W the Delassus operator in impulses (N s,
/// symmetric), q the points' local velocities without impulse (m/s, the normal target velocity
/// folded in), mu; unknown k is contact k of the ContactList (`order` as for the polish). Plain
/// Signorini-Coulomb-Newton laws only (the caller checks). For SolverOptions::problem_observer.
LocalProblem explicit_contact_problem(const CompactProblem& compact, std::span<const std::size_t> order);

}  // namespace rubble
