#pragma once
// How a step's sweeps walk the plan (nlgs_solver/README.md, "Sweep order and threads"): the
// plan itself (SweepPlan, plan_sweep) is declared in nlgs.hpp and made in sweep_plan.cpp; this
// header holds the order in which its groups are visited, serially or by several threads.
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <span>
#include <vector>

#include "nlgs_solver/nlgs.hpp"
#include "nlgs_solver/sweep.hpp"

namespace rubble {

/// Calls visit(g) once for every group of the plan, each group after both subtrees below it.
/// Serially: group after group (phase by phase). In parallel (one OpenMP team, no barrier inside):
/// the threads take the leaves' groups in contiguous runs (a static schedule: with 2 threads and
/// 16 blocks, thread 0 holds blocks 0-7 and thread 1 blocks 8-15, one subtree each, so only the
/// root's group waits for the other thread; a dynamic schedule hands the last leaves out together
/// and leaves one thread to climb the whole path from the last leaf to the root alone, ~12% of the
/// contacts of the mixed deposit), and whoever finishes the second child of a tree node visits
/// that node's group next, and so on up to the root (an atomic arrival count per node; its
/// acquire-release ordering makes the sibling's velocity writes visible). Groups that may run
/// concurrently share no moving body (walls are never written), so every contact is updated from
/// the same data as in the serial order: the result does not depend on the thread count.
/// (A barrier per phase instead costs 5 synchronisations per sweep; on a loaded machine each is a
/// scheduler time slice.)
///
/// `leaf_work` (optional, one entry per leaf group and its size only then used): the work each
/// leaf took last time; the contiguous runs are then cut at equal shares of it instead of equal
/// numbers of leaves (after open points are skipped the leaves' work is uneven). Which thread
/// visits a group never changes what the visit computes, so this cannot change a result.
template <class Visit>
void visit_groups(const SweepPlan& plan, bool parallel, const Visit& visit, std::span<const double> leaf_work = {}) {
  const std::size_t groups = plan.group_start.size() - 1;
  if (!parallel) {
    for (std::size_t g = 0; g < groups; ++g) visit(g);
    return;
  }
  std::vector<std::atomic<int>> arrivals(groups);
  for (auto& count : arrivals) count.store(0, std::memory_order_relaxed);
  const auto leaves = static_cast<std::size_t>(plan.phase_start[1]);
  double total = 0.0;
  if (leaf_work.size() == leaves) {
    for (const double w : leaf_work) total += w;
  }
#pragma omp parallel
  {
    // This thread's run of leaves: the leaves whose work midpoint falls in its share (equal
    // counts, as a static schedule, without the work).
    const int thread = omp_get_thread_num();
    const int threads = omp_get_num_threads();
    std::size_t first = leaves, last = leaves;
    double before = 0.0;
    for (std::size_t leaf = 0; leaf < leaves; ++leaf) {
      const double share = total > 0.0 ? (before + 0.5 * leaf_work[leaf]) / total
                                       : (static_cast<double>(leaf) + 0.5) / static_cast<double>(leaves);
      if (total > 0.0) before += leaf_work[leaf];
      // Shares grow with the leaf, so each thread's leaves are contiguous; every leaf has an owner.
      const int owner = std::clamp(static_cast<int>(share * threads), 0, threads - 1);
      const bool mine = owner == thread;
      if (mine && first == leaves) first = leaf;
      if (mine) last = leaf + 1;
    }
    for (std::size_t leaf = first; leaf < last; ++leaf) {
      std::size_t g = leaf;
      visit(g);
      // Climb while this thread completed the second child of the parent.
      while (plan.parent_group[g] < groups) {
        g = plan.parent_group[g];
        if (arrivals[g].fetch_add(1, std::memory_order_acq_rel) == 0) break;  // the sibling's thread goes on
        visit(g);
      }
    }
  }
}

/// Per-group scratch of planned_sweep, kept across the sweeps of a step.
struct GroupSweeps {
  std::vector<SweepResult> result;  ///< each group's sums of the last sweep
  std::vector<double> seconds;      ///< each group's own sweep time (threaded sweeps only)
  std::vector<double> leaf_work;    ///< the leaves' times of the sweep before (visit_groups' shares)
};

/// One sweep of a problem whose point p is position p of the plan's order, group by group
/// (visit_groups). The groups' residual sums are added in group order, so the stopping test does
/// not depend on the thread count either. In parallel, `groups.seconds` receives each group's own
/// sweep time (their sum is what the sweep costs on one thread), so the caller can tell when the
/// threads spend longer waiting for a core than working.
template <class Problem>
SweepResult planned_sweep(Problem& problem, const SweepPlan& plan, std::span<const std::size_t> positions,
                          double relaxation, bool parallel, GroupSweeps& groups) {
  using Clock = std::chrono::steady_clock;
  const std::size_t count = plan.group_start.size() - 1;
  groups.result.assign(count, SweepResult{});
  const auto leaves = static_cast<std::size_t>(plan.phase_start[1]);
  // Last sweep's leaf times (none before the first threaded sweep of the step), copied: the
  // threads overwrite `seconds` while the others are still reading the shares.
  if (parallel && groups.seconds.size() == count) {
    groups.leaf_work.assign(groups.seconds.begin(), groups.seconds.begin() + static_cast<std::ptrdiff_t>(leaves));
  } else {
    groups.leaf_work.clear();
  }
  if (parallel) groups.seconds.assign(count, 0.0);
  visit_groups(
      plan, parallel,
      [&](std::size_t g) {
        const std::size_t first = plan.group_start[g], last = plan.group_start[g + 1];
        if (first == last) return;
        // Timed only when threaded (clock_gettime was 9 % of a 27-sphere scene's serial sweeps).
        const auto begin = parallel ? Clock::now() : Clock::time_point{};
        const std::span<const std::size_t> part(positions.data() + first, last - first);
        groups.result[g] = nlgs_sweep(problem, part, relaxation);
        if (parallel) groups.seconds[g] = std::chrono::duration<double>(Clock::now() - begin).count();
      },
      groups.leaf_work);
  SweepResult sum;
  for (const SweepResult& r : groups.result) {
    sum.residual_squared += r.residual_squared;
    sum.impulse_squared += r.impulse_squared;
    sum.passed_by += r.passed_by;
  }
  return sum;
}

}  // namespace rubble
