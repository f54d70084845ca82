#pragma once
// Stage 5 of the step: the frictional contact problem of the active contacts, solved by
// nonlinear Gauss-Seidel (NLGS; Jean 1999): contact after contact, the 3x3 local
// problem is solved exactly with the other contacts' impulses frozen, and the two bodies'
// velocities are updated at once, so no global matrix is assembled.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/contact.hpp"
#include "core/integrator.hpp"
#include "core/model.hpp"
#include "core/state.hpp"
#include "nlgs_solver/overlap_recovery.hpp"

namespace rubble {

struct LocalProblem;  // local_problem.hpp (which includes this header)

/// Settings of the NLGS solver.
struct SolverOptions {
  double tolerance = 1e-4;    ///< stop when the sweep residual (see nlgs_solver/README.md) is below this
  int max_iterations = 1000;  ///< sweeps at most
  /// omega in (0, 2): r <- omega r_local + (1 - omega) r_old. Above 1, only between a plain first
  /// sweep and plain last sweeps (nlgs_solver/README.md, "Over-relaxation").
  double relaxation = 1.5;
  bool warm_start = true;  ///< start from last step's impulses of persistent contacts
  /// The position-level recovery of overlaps left at the end of the step (overlap_recovery.hpp):
  /// it moves positions only, so it creates no kinetic energy.
  OverlapRecoveryOptions overlap_recovery{};
  /// Sweeps after which, if not converged, the whole contact problem is polished by Newton steps
  /// (nlgs_solver/README.md, "Newton polish"); later attempts after twice as many sweeps each.
  /// Gauss-Seidel crawls on hyperstatic stacks (four points per face) and its error then carries
  /// over from step to step; the polish ends that. 0 disables it.
  int polish_after = 40;
  int polish_iterations = 20;  ///< Newton (Levenberg-Marquardt) steps per attempt at most
  /// Larger problems are not polished: the sparse factorisation of a compact 3D aggregate fills
  /// in like a 3D mesh (measured: 13-78 s a polish at 5 800 polyhedron contact points, against
  /// 0.07 s for 40 sweeps), so the polish is for stacks and small piles.
  std::size_t polish_max_contacts = 500;
  /// Polishes per step at most (each after twice the sweeps of the previous one).
  int polish_attempts_per_step = 2;
  /// Steps with more than polish_max_contacts points: every polish_after sweeps, when a few
  /// points hold the residual, the points between their grains (at most this many) are polished
  /// with the others held fixed (nlgs_solver/README.md, "The stalled cluster's polish"). 0 disables it.
  std::size_t cluster_polish_max_contacts = 256;
  /// Spatial blocks of the sweep (nlgs_solver/README.md, "Sweep order and threads"): the moving
  /// bodies are cut into this many ranges of their Morton (Z-order) sequence, with equal contact
  /// counts; blocks sharing no body are swept concurrently. It fixes the sweep order, so results
  /// depend on it but never on the number of threads. 1 = one block (a plain sequential sweep in
  /// Morton order).
  int block_count = 16;
  /// Sweeps remembered by the Anderson acceleration of the sweeps (nlgs_solver/README.md,
  /// "Anderson acceleration"): after each sweep the iterate is the combination of the last ones
  /// whose change is least, projected on the cones. 0 disables it.
  int anderson_depth = 0;
  /// Steps with more contact points than this are not accelerated: the history holds 2
  /// anderson_depth float copies of the loaded points' impulses and five double ones (about
  /// 0.25 kB a loaded point at depth 5).
  std::size_t anderson_max_contacts = 20000;
  /// When set, called with each step's contact problem (explicit W, q, mu; polish.hpp,
  /// explicit_contact_problem) before the sweeps: to write it as an FCLib file that other solvers
  /// replay (bench_matched_accuracy --write-fclib, bench_siconos). Plain Signorini-Coulomb-Newton
  /// laws only: solve_contacts throws std::invalid_argument for a scene with cohesion, rolling or
  /// twisting resistance or tangential restitution. Empty (the default) costs one test a step.
  std::function<void(const LocalProblem&)> problem_observer;
};

/// What one solve did, for the step's report.
struct SolverStats {
  int iterations = 0;               ///< sweeps done
  double residual = 0.0;            ///< natural-map residual ||F|| / ||q_closing|| at exit (see README)
  bool converged = false;           ///< residual <= tolerance within max_iterations
  int polish_attempts = 0;          ///< Newton polishes started (see SolverOptions::polish_after)
  int newton_iterations = 0;        ///< Newton steps taken by those polishes and the cluster polishes
  int cluster_polishes = 0;         ///< stalled clusters polished (SolverOptions::cluster_polish_max_contacts)
  std::size_t active_contacts = 0;  ///< contacts carrying a normal impulse at exit
  /// Visits of open points the sweeps passed by, summed over the sweeps (nlgs_solver/README.md,
  /// "Open contacts skipped"): each would have left the point open and changed nothing.
  std::size_t passed_by = 0;
};

/// The fixed order in which every sweep of one step visits the contacts, and which parts of it may
/// run concurrently. The contacts are split into groups: one per node of a binary tree over the
/// `block_count` spatial blocks. A leaf's group holds the contacts whose moving bodies all lie in
/// that block; an inner node's group holds the contacts joining its two subtrees. Groups are listed
/// phase by phase (phase = node height: leaves first, the root last); the groups of one phase
/// share no moving body, so they can be swept in any order or concurrently with the same result;
/// more generally any order that sweeps a node's group after its two children's subtrees gives
/// the same result. Within a group, contacts are in Morton order of their contact point.
struct SweepPlan {
  std::vector<std::size_t> order;         ///< contact indices, group after group
  std::vector<std::size_t> group_start;   ///< groups + 1 offsets into `order`
  std::vector<std::size_t> phase_start;   ///< phases + 1 offsets into the groups
  std::vector<std::size_t> parent_group;  ///< per group, its tree parent's group (the root: groups)
  std::vector<std::size_t> body_order;    ///< the contacts' moving bodies in Morton order
};

/// The sweep order of `contacts` (see SweepPlan) from the bodies' positions at the start of the
/// step; deterministic (ties broken by index). `block_count` >= 1. In sweep_plan.cpp.
SweepPlan plan_sweep(const Model& model, const State& state, const ContactList& contacts, int block_count);

/// Fills each contact's arms, Delassus block, law and normal target velocity from the model, the
/// state at the start of the step and the free velocities (LMGC90's "prep_nlgs"). In prepare.cpp.
void prepare_contacts(const Model& model, const State& state, const BodyVelocities& free_velocity,
                      const IntegratorOptions& integrator, const SolverOptions& options, ContactList& contacts);

/// Solves for the contact impulses and updates `velocity` (which holds the free velocity on
/// entry and v_{n+1} = v_free + M^-1 H r on exit). Contacts hold warm-start impulses on entry.
/// In nlgs.cpp: warm start, sweeps until converged (with Newton polishes, polish.cpp), final residual.
SolverStats solve_contacts(const Model& model, const State& state, const SolverOptions& options, ContactList& contacts,
                           BodyVelocities& velocity);

}  // namespace rubble
