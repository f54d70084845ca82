// solve_contacts: warm start, sweeps until converged, final residual (nlgs_solver/README.md).
// The parts live in files of their own: prepare.cpp (Delassus blocks, targets), sweep_plan.cpp
// (the sweep order), compact_problem.cpp (the copy the sweeps work on), polish.cpp (Newton).
#include "nlgs_solver/nlgs.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/parallel.hpp"
#include "nlgs_solver/anderson.hpp"
#include "nlgs_solver/compact_problem.hpp"
#include "nlgs_solver/coulomb.hpp"
#include "nlgs_solver/polish.hpp"
#include "nlgs_solver/sweep_plan.hpp"

namespace rubble {
namespace {

using Clock = std::chrono::steady_clock;

/// The scale of the residual (nlgs_solver/README.md, "Convergence criterion").
struct ResidualScale {
  /// ||q_closing||^2: the local velocities with no contact impulse (free velocity minus target) of
  /// the contacts the free motion drives together (q_n < 0); ||q||^2 of all if none closes.
  double closing_squared = 0.0;
  double all_squared = 0.0;  ///< ||q||^2 over every contact (the polish's FCLib measure)
};

/// ||q_closing|| and ||q|| of the compact problem before any impulse is applied. Open contacts of
/// falling grains have q_n of the order gap / h: counting them (the earlier ||q||) let a deposit
/// whose few loaded contacts were far from converged pass the test. Summed group by group, then
/// in group order (the same sum for any thread count).
ResidualScale residual_scale(const CompactProblem& compact, const SweepPlan& plan, bool parallel) {
  const std::size_t groups = plan.group_start.size() - 1;
  std::vector<double> group_closing(groups, 0.0), group_all(groups, 0.0);
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(groups); ++i) {
    const auto g = static_cast<std::size_t>(i);
    double closing = 0.0, all = 0.0;
    for (std::size_t p = plan.group_start[g]; p < plan.group_start[g + 1]; ++p) {
      const Vec3 q = compact.full_local_velocity(p);
      all += q.squaredNorm();
      if (q.x() < 0.0) closing += q.squaredNorm();
    }
    group_closing[g] = closing;
    group_all[g] = all;
  }
  ResidualScale scale;
  for (std::size_t g = 0; g < groups; ++g) {
    scale.closing_squared += group_closing[g];
    scale.all_squared += group_all[g];
  }
  if (scale.closing_squared == 0.0) scale.closing_squared = scale.all_squared;
  return scale;
}

/// Warm start: the velocities must include the starting impulses (projected inside the cone),
/// applied in the sweeps' order and concurrency (visit_groups). Cohesion (ContactLaw::cohesion):
/// the sweeps solve for the shifted impulse r~ = r + c e_n in the plain Signorini-Coulomb cone,
/// the constant -c e_n being part of the free motion; the impulses are r~ until the end of the
/// solve (the polish works on the same shifted problem).
void apply_warm_start(const SweepPlan& plan, const ContactList& contacts, bool cohesive, bool parallel,
                      CompactProblem& compact) {
  visit_groups(plan, parallel, [&](std::size_t g) {
    for (std::size_t p = plan.group_start[g]; p < plan.group_start[g + 1]; ++p) {
      CompactProblem::Point& point = compact.points[p];
      const double cohesive_impulse = cohesive ? contacts[plan.order[p]].cohesive_impulse : 0.0;
      Vec3& r = point.impulse;
      r.x() += cohesive_impulse;
      r = project_onto_coulomb_cone(r, point.friction_coefficient);
      const Vec3 applied(r.x() - cohesive_impulse, r.y(), r.z());
      if (applied != Vec3::Zero()) compact.apply_impulse_change(p, applied);
    }
  });
}

/// Whether the sweeps still make progress: after every `window` sweeps, the window's best residual
/// must be at most `progress` times the previous window's. Read by the over-relaxation schedule
/// and by the Anderson mixing, which each stop for the step on the first window without it.
struct ProgressWindow {
  static constexpr int window = 20;
  static constexpr double progress = 0.9;

  int sweeps = 0;  ///< sweeps observed so far
  double window_best = std::numeric_limits<double>::infinity();
  double previous_window_best = std::numeric_limits<double>::infinity();

  /// After each sweep, with its relative residual: false when it ends a window without progress.
  bool observe(double relative_residual) {
    ++sweeps;
    window_best = std::min(window_best, relative_residual);
    if (sweeps % window != 0) return true;
    const bool progressed = !(window_best > progress * previous_window_best);
    previous_window_best = window_best;
    window_best = std::numeric_limits<double>::infinity();
    return progressed;
  }
};

/// When the sweeps over-relax (SolverOptions::relaxation > 1; nlgs_solver/README.md, "Over-
/// relaxation"). Projected successive over-relaxation moves each point past its local solution,
/// which speeds up the slow, smooth modes that plain Gauss-Seidel removes one layer of contacts a
/// sweep (Young 1954; Cryer 1971 for the projected form), but a frictional problem whose points
/// change status can stall under it. So omega is used only between a plain first sweep (most
/// warm-started steps end there) and plain last sweeps: from the sweep whose residual is within
/// `near_tolerance` times the tolerance, so that the test ending the solve is a plain sweep's, and
/// for good once a window of sweeps has made no progress (ProgressWindow). It reads the sweep
/// residuals only, which do not depend on the thread count.
struct RelaxationSchedule {
  static constexpr double near_tolerance = 3.0;

  double requested = 1.0;     ///< SolverOptions::relaxation
  double tolerance = 0.0;     ///< SolverOptions::tolerance
  bool plain = false;         ///< omega = 1 from now on, for this step
  int sweeps = 0;             ///< sweeps observed so far
  ProgressWindow progress{};  ///< over the over-relaxed sweeps (and the first)

  /// omega for the next sweep (under-relaxation, omega < 1, is used as asked in every sweep).
  double relaxation() const {
    if (requested <= 1.0) return requested;
    return plain || sweeps == 0 ? 1.0 : requested;
  }

  /// After each sweep, with its relative residual ||F|| / sqrt(closing^2 + impulses^2).
  void observe(double relative_residual) {
    ++sweeps;
    if (requested <= 1.0 || plain) return;
    if (relative_residual <= near_tolerance * tolerance) plain = true;
    if (!progress.observe(relative_residual)) plain = true;
  }
};

/// Sweeps (planned_sweep) until the sweep residual meets the tolerance or max_iterations sweeps
/// are done, with Newton polishes after polish_after, 2 polish_after, ... sweeps when `may_polish`.
/// Sets the stats' iterations, converged and polish counts. `parallel` is cleared when a threaded
/// sweep took longer than its work on one thread: the threads waited for cores busy with other
/// processes, so the rest of the step is swept serially. Both paths give the same iterate to the
/// bit, so this timing-based choice cannot change the result.
SolverStats sweep_until_converged(const SolverOptions& options, const SweepPlan& plan, const ResidualScale& scale,
                                  bool may_polish, bool may_polish_cluster, CompactProblem& compact, bool& parallel) {
  SolverStats stats;
  GroupSweeps groups;
  std::vector<std::size_t> positions(compact.size());
  for (std::size_t p = 0; p < positions.size(); ++p) positions[p] = p;
  ExtendedProblem extended{compact};
  const bool plain = compact.rotation.empty() && compact.tangential_target.empty();
  int next_polish = options.polish_after;
  RelaxationSchedule schedule{.requested = options.relaxation, .tolerance = options.tolerance};
  // Not with rotation blocks or tangential targets (their impulses and targets are outside the
  // mixed state), nor past anderson_max_contacts (the memory of its history).
  std::optional<AndersonAcceleration> anderson;
  if (plain && options.anderson_depth > 0 && compact.size() <= options.anderson_max_contacts) {
    anderson.emplace(compact, options.anderson_depth);
  }
  // The mixing can stall where the sweeps alone would not (a status that flips back and forth):
  // a window without progress ends it for the step, leaving the sweeps no worse than without it.
  ProgressWindow mixing_progress;
  for (stats.iterations = 1; stats.iterations <= options.max_iterations; ++stats.iterations) {
    const auto sweep_start = parallel ? Clock::now() : Clock::time_point{};
    const double relaxation = schedule.relaxation();
    if (anderson) anderson->before_sweep(compact);
    const SweepResult sweep = plain ? planned_sweep(compact, plan, positions, relaxation, parallel, groups)
                                    : planned_sweep(extended, plan, positions, relaxation, parallel, groups);
    stats.passed_by += sweep.passed_by;
    if (parallel) {
      double work = 0.0;
      for (const double t : groups.seconds) work += t;
      if (std::chrono::duration<double>(Clock::now() - sweep_start).count() > work) parallel = false;
    }
    const double scale_squared = scale.closing_squared + sweep.impulse_squared;
    // Only a plain (or under-relaxed) sweep may end the solve: an over-relaxed sweep's residual,
    // taken before each point's update, can understate the residual after it.
    if (std::sqrt(sweep.residual_squared) <= options.tolerance * std::sqrt(scale_squared) && relaxation <= 1.0) {
      stats.converged = true;
      break;
    }
    const double relative_residual =
        std::sqrt(sweep.residual_squared / std::max(scale_squared, std::numeric_limits<double>::min()));
    schedule.observe(relative_residual);
    if (anderson && !mixing_progress.observe(relative_residual)) anderson.reset();
    if (anderson) anderson->after_sweep(compact, relative_residual, relaxation);
    if (may_polish && stats.iterations == next_polish && stats.polish_attempts < options.polish_attempts_per_step) {
      ++stats.polish_attempts;
      next_polish *= 2;
      // The polish measures ||F|| / ||q|| over every contact: the same test, rescaled.
      const double tolerance =
          scale.all_squared > 0.0
              ? options.tolerance * std::sqrt((scale.closing_squared + sweep.impulse_squared) / scale.all_squared)
              : options.tolerance;
      const PolishOutcome polished = polish_compact_problem(compact, plan.order, options.polish_iterations, tolerance);
      compact.forget_open_points();  // the polish may have loaded points the sweeps left open
      if (anderson) anderson->restart();
      stats.newton_iterations += polished.newton_steps;
      if (polished.converged) {
        stats.converged = true;
        break;
      }
    } else if (may_polish_cluster && stats.iterations % options.polish_after == 0) {
      // Too large to polish whole: a stall is often a few grains whose points fight each other
      // (nlgs_solver/README.md, "The stalled cluster's polish"). Its target, a tenth of the
      // residual the tolerance allows, leaves the next sweep below the tolerance when the
      // cluster held nearly all of it.
      const ClusterPolishOptions cluster{.max_points = options.cluster_polish_max_contacts,
                                         .iterations = options.polish_iterations,
                                         .residual_target = 0.1 * options.tolerance * std::sqrt(scale_squared)};
      const ClusterPolishOutcome polished = polish_stalled_cluster(compact, cluster);
      stats.newton_iterations += polished.newton_steps;
      if (polished.points > 0) {
        ++stats.cluster_polishes;
        if (anderson) anderson->restart();
      }
    }
  }
  stats.iterations = std::min(stats.iterations, options.max_iterations);
  return stats;
}

/// The end-of-step residual on the compact copy (one pass, no local solves, group by group, then
/// in group order), the contacts' statuses and the active count, into `stats`.
void final_residual(const CompactProblem& compact, const SweepPlan& plan, const ResidualScale& scale, bool parallel,
                    ContactList& contacts, SolverStats& stats) {
  const std::size_t groups = plan.group_start.size() - 1;
  std::vector<double> group_residual(groups, 0.0), group_impulse(groups, 0.0);
  std::vector<std::size_t> group_active(groups, 0);
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(groups); ++i) {
    const auto g = static_cast<std::size_t>(i);
    for (std::size_t p = plan.group_start[g]; p < plan.group_start[g + 1]; ++p) {
      const CompactProblem::Point& point = compact.points[p];
      const Vec3& r = point.impulse;
      group_residual[g] += compact.residual_squared(p);
      group_impulse[g] += (point.delassus(0, 0) * r).squaredNorm();
      const auto [spin_residual, spin_impulse] = compact.rotation_residual(p);
      group_residual[g] += spin_residual;
      group_impulse[g] += spin_impulse;
      if (r.x() > 0.0) ++group_active[g];
      contacts[plan.order[p]].status = r.x() <= 0.0 ? ContactStatus::open
                                       : tangential_norm(r) >= point.friction_coefficient * r.x() * (1.0 - 1e-9)
                                           ? ContactStatus::sliding
                                           : ContactStatus::sticking;
    }
  }
  double residual_squared = 0.0, impulse_squared = 0.0;
  for (std::size_t g = 0; g < groups; ++g) {
    residual_squared += group_residual[g];
    impulse_squared += group_impulse[g];
    stats.active_contacts += group_active[g];
  }
  const double scale_squared = scale.closing_squared + impulse_squared;
  stats.residual = scale_squared > 0.0 ? std::sqrt(residual_squared / scale_squared) : std::sqrt(residual_squared);
}

/// Whether the polish knows the scene's laws: Signorini-Coulomb-Newton, with or without cohesion
/// (no rolling or twisting resistance, no tangential restitution).
bool may_polish_laws(const Model& model) {
  return !model.contact_laws.any_resists_rotation() && !model.contact_laws.any_tangential_restitution();
}

}  // namespace

SolverStats solve_contacts(const Model& model, const State& state, const SolverOptions& options, ContactList& contacts,
                           BodyVelocities& velocity) {
  // No polish with rolling or twisting resistance or tangential restitution: the polish knows the
  // Signorini-Coulomb-Newton law only.
  const bool polish_laws = options.polish_after > 0 && may_polish_laws(model);
  const bool may_polish =
      polish_laws && contacts.size() <= options.polish_max_contacts && options.polish_attempts_per_step > 0;
  const bool may_polish_cluster =
      polish_laws && contacts.size() > options.polish_max_contacts && options.cluster_polish_max_contacts > 0;
  const SweepPlan plan = plan_sweep(model, state, contacts, options.block_count);
  // Small problems, or one thread: the same order without an OpenMP team (even a one-thread team
  // costs a futex round trip per sweep).
  bool parallel = static_cast<std::ptrdiff_t>(contacts.size()) >= min_parallel_items && plan.group_start.size() > 2 &&
                  omp_get_max_threads() > 1;
  // The copy's velocities are the free velocities and its impulses last step's, not yet applied.
  CompactProblem compact = gather_compact_problem(model, state, plan, contacts, velocity, parallel);
  const ResidualScale scale = residual_scale(compact, plan, parallel);
  const bool cohesive = model.contact_laws.any_cohesive();
  if (options.problem_observer) {
    if (cohesive || !may_polish_laws(model)) {
      throw std::invalid_argument(
          "problem_observer: the contact problem is written for plain Signorini-Coulomb-Newton laws only (this "
          "scene has cohesion, rolling or twisting resistance or tangential restitution)");
    }
    options.problem_observer(explicit_contact_problem(compact, plan.order));
  }
  apply_warm_start(plan, contacts, cohesive, parallel, compact);
  warm_start_rotations(compact);

  SolverStats stats;
  if (contacts.empty()) {
    stats.converged = true;
  } else {
    stats = sweep_until_converged(options, plan, scale, may_polish, may_polish_cluster, compact, parallel);
    scatter_compact_problem(model, plan, compact, contacts, velocity, parallel);
  }
  final_residual(compact, plan, scale, parallel, contacts, stats);
  if (cohesive) {
    for (Contact& c : contacts) c.impulse.x() -= c.cohesive_impulse;  // back from r~ to r
  }
  return stats;
}

}  // namespace rubble
