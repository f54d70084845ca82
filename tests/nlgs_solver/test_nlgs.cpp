// The simulation's NLGS on small sphere packings: equilibrium against momentum balance, the
// reported residual, warm start; and the sweep order (plan_sweep): its groups of one phase share no
// moving body, the threaded sweeps equal a plain sequential Gauss-Seidel sweep in the plan's order
// bit for bit, whatever the thread count.
#include <gtest/gtest.h>
#include <omp.h>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>
#include <span>
#include <stdexcept>

#include "nlgs_solver/compact_problem.hpp"
#include "nlgs_solver/nlgs.hpp"
#include "nlgs_solver/sweep.hpp"
#include "nlgs_solver/sweep_plan.hpp"

#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

// Three spheres touching on a floor and a fourth resting on them (a tetrahedral pile), at rest.
TestScene pile(double mu) {
  TestScene s(2500, mu, 0.0);
  s.uniform_gravity(9.81);
  const double r = 0.1;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  const double circumradius = 2 * r / std::sqrt(3.0);
  for (int k = 0; k < 3; ++k) {
    const double a = 2.0 * M_PI * k / 3.0;
    s.sphere(r, Vec3(circumradius * std::cos(a), circumradius * std::sin(a), r));
  }
  // Top sphere touching all three: height above their centres sqrt((2r)^2 - circumradius^2).
  s.sphere(r, Vec3(0, 0, r + std::sqrt(4 * r * r - circumradius * circumradius)));
  return s;
}

TEST(Nlgs, FloorCarriesTheWholeWeightOfAStaticPile) {
  TestScene s = pile(0.6);
  s.options.solver.tolerance = 1e-9;
  s.options.solver.max_iterations = 100000;
  s.advance();
  ASSERT_TRUE(s.last_report.solver.converged)
      << "residual " << s.last_report.solver.residual << " after " << s.last_report.solver.iterations << " sweeps";
  double floor_impulse = 0.0;
  double weight = 0.0;
  for (std::size_t b = 1; b < s.model.body_count(); ++b) weight += s.model.mass[b] * 9.81;
  for (const Contact& c : s.workspace.carry.contacts) {
    if (c.id.body_a == 0 || c.id.body_b == 0) floor_impulse += (c.frame * c.impulse).z();
  }
  // Momentum balance over one step with the pile at rest: floor impulse = total weight * h.
  EXPECT_NEAR(floor_impulse, weight * s.options.integrator.time_step, 1e-7 * weight * s.options.integrator.time_step);
  // And every contact honours Coulomb's cone.
  for (const Contact& c : s.workspace.carry.contacts) {
    EXPECT_LE(std::hypot(c.impulse.y(), c.impulse.z()), c.friction_coefficient * c.impulse.x() * (1 + 1e-12));
  }
}

TEST(Nlgs, ReportedResidualIsBelowTheToleranceWhenConverged) {
  for (const double tolerance : {1e-3, 1e-6, 1e-9}) {
    TestScene s = pile(0.3);
    s.options.solver.tolerance = tolerance;
    s.options.solver.max_iterations = 100000;
    s.options.solver.warm_start = false;
    s.advance();
    EXPECT_TRUE(s.last_report.solver.converged);
    // The stopping test uses the residual seen during the last sweep; the end-of-step residual
    // may differ slightly but must stay within an order of magnitude.
    EXPECT_LE(s.last_report.solver.residual, 10 * tolerance) << "tolerance " << tolerance;
  }
}

TEST(Nlgs, WarmStartCutsTheIterationsOfAPersistentPile) {
  TestScene cold = pile(0.3);
  cold.options.solver.tolerance = 1e-8;
  cold.options.solver.warm_start = false;
  TestScene warm = pile(0.3);
  warm.options.solver.tolerance = 1e-8;
  int cold_iterations = 0, warm_iterations = 0;
  for (int k = 0; k < 50; ++k) {
    cold.advance();
    warm.advance();
    if (k > 0) {
      cold_iterations += cold.last_report.solver.iterations;
      warm_iterations += warm.last_report.solver.iterations;
    }
  }
  EXPECT_LT(warm_iterations, cold_iterations / 2) << "warm " << warm_iterations << " cold " << cold_iterations;
}

// A box of 12 x 12 x 8 spheres of radius 5 cm on a 10 cm simple cubic grid, every sphere touching
// its six neighbours (and the floor for the bottom layer): ~3 600 contacts, more than
// min_parallel_items (1 024), so the sweeps take the threaded path on two threads. Columns stand
// exactly on each other, so at rest the floor carries the whole weight.
TestScene packed_box(double mu, const Vec3& jitter_velocity = Vec3::Zero()) {
  TestScene s(2500, mu, 0.0);
  s.uniform_gravity(9.81);
  s.options.integrator.time_step = 1e-3;
  s.options.solver.tolerance = 1e-4;
  s.options.solver.max_iterations = 200;
  const double r = 0.05;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  int i = 0;
  for (int z = 0; z < 8; ++z) {
    for (int y = 0; y < 12; ++y) {
      for (int x = 0; x < 12; ++x, ++i) {
        // A deterministic small velocity per grain (no random generator), so the problem is not
        // symmetric.
        const Vec3 v = jitter_velocity * static_cast<double>((i * 7919) % 11 - 5) / 5.0;
        s.sphere(r, Vec3(2 * r * x, 2 * r * y, r + 2 * r * z), v);
      }
    }
  }
  return s;
}

TEST(SweepPlan, GroupsOfOnePhaseShareNoMovingBodyAndTheOrderIsAPermutation) {
  TestScene s = packed_box(0.5, Vec3(0.05, -0.03, 0.02));
  s.options.solver.max_iterations = 5;  // only the contacts matter here
  s.steps(2);
  const ContactList& contacts = s.workspace.carry.contacts;
  ASSERT_GT(contacts.size(), 3000u);
  for (const int blocks : {1, 2, 5, 16, 64}) {
    const SweepPlan plan = plan_sweep(s.model, s.state, contacts, blocks);
    // Every contact exactly once.
    ASSERT_EQ(plan.order.size(), contacts.size());
    EXPECT_EQ(std::set<std::size_t>(plan.order.begin(), plan.order.end()).size(), contacts.size());
    // body_order: each moving body of the contacts exactly once.
    std::set<std::size_t> moving;
    for (const Contact& c : contacts) {
      for (const std::size_t body : {std::size_t{c.id.body_a}, std::size_t{c.id.body_b}}) {
        if (!s.model.is_fixed(body)) moving.insert(body);
      }
    }
    EXPECT_EQ(plan.body_order.size(), moving.size());
    EXPECT_EQ(std::set<std::size_t>(plan.body_order.begin(), plan.body_order.end()), moving);
    // A binary tree over the blocks: 2K - 1 groups.
    ASSERT_EQ(plan.group_start.size(), static_cast<std::size_t>(2 * blocks));
    EXPECT_EQ(plan.group_start.back(), contacts.size());
    EXPECT_EQ(plan.phase_start.back(), plan.group_start.size() - 1);
    // Phases = tree height + 1 = ceil(log2 K) + 1.
    EXPECT_EQ(plan.phase_start.size() - 1, static_cast<std::size_t>(std::ceil(std::log2(blocks))) + 1) << blocks;
    for (std::size_t p = 0; p + 1 < plan.phase_start.size(); ++p) {
      std::vector<int> owner(s.model.body_count(), -1);  // group that moved each body in this phase
      for (std::size_t g = plan.phase_start[p]; g < plan.phase_start[p + 1]; ++g) {
        for (std::size_t i = plan.group_start[g]; i < plan.group_start[g + 1]; ++i) {
          const Contact& c = contacts[plan.order[i]];
          for (const std::size_t body : {std::size_t{c.id.body_a}, std::size_t{c.id.body_b}}) {
            if (s.model.is_fixed(body)) continue;
            if (owner[body] < 0) owner[body] = static_cast<int>(g);
            ASSERT_EQ(owner[body], static_cast<int>(g)) << "body " << body << " in groups " << owner[body] << " and "
                                                        << g << " of phase " << p << ", " << blocks << " blocks";
          }
        }
      }
    }
    // The tree: every group but the root has a parent in a later phase; each inner group has two
    // children.
    ASSERT_EQ(plan.parent_group.size(), plan.group_start.size() - 1);
    const std::size_t groups = plan.parent_group.size();
    std::vector<int> children(groups, 0);
    auto phase_of = [&](std::size_t g) {
      return std::upper_bound(plan.phase_start.begin(), plan.phase_start.end(), g) - plan.phase_start.begin();
    };
    for (std::size_t g = 0; g + 1 < groups; ++g) {
      ASSERT_LT(plan.parent_group[g], groups);
      EXPECT_GT(phase_of(plan.parent_group[g]), phase_of(g));
      ++children[plan.parent_group[g]];
    }
    EXPECT_EQ(plan.parent_group[groups - 1], groups);  // the root
    for (std::size_t g = 0; g < groups; ++g) EXPECT_EQ(children[g], g < plan.phase_start[1] ? 0 : 2) << g;
    if (blocks == 16) {
      // Leaves hold most contacts (the point of spatial blocks): the interface contacts swept at
      // the root, on one thread, are a thin layer (measured: 5.8% here, the leaves 75%).
      const std::size_t root =
          plan.group_start[plan.group_start.size() - 1] - plan.group_start[plan.group_start.size() - 2];
      const std::size_t leaves = plan.group_start[plan.phase_start[1]];
      EXPECT_LT(static_cast<double>(root), 0.1 * static_cast<double>(contacts.size()));
      EXPECT_GT(static_cast<double>(leaves), 0.6 * static_cast<double>(contacts.size()));
    }
  }
  EXPECT_THROW(plan_sweep(s.model, s.state, contacts, 0), std::invalid_argument);
}

/// An independent, plain sequential Gauss-Seidel over the bodies' velocities (the sweep's Problem
/// interface, sweep.hpp), written here from the formulas of nlgs_solver/README.md.
struct ReferenceProblem {
  const Model& model;
  ContactList& contacts;
  BodyVelocities& velocity;
  std::vector<Mat3> inverse_inertia;

  std::size_t size() const { return contacts.size(); }
  const Mat3& delassus(std::size_t k) const { return contacts[k].delassus; }
  // Inverted at every call, as the local solver did before the compact problem kept the inverse:
  // the threaded sweeps below must give the same bits from their stored one.
  Mat3 delassus_inverse(std::size_t k) const { return contacts[k].delassus.inverse(); }
  double friction_coefficient(std::size_t k) const { return contacts[k].friction_coefficient; }
  Vec3& impulse(std::size_t k) { return contacts[k].impulse; }
  Vec3 local_velocity(std::size_t k) const {
    const Contact& c = contacts[k];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    // The compact problem's arithmetic (the same evaluation order), on the contact list and the
    // body arrays instead of the copy.
    Vec3 u = relative_local_velocity(c.frame, c.arm_a, c.arm_b, velocity.linear[a], velocity.angular[a],
                                     velocity.linear[b], velocity.angular[b]);
    u.x() -= c.normal_velocity_target;
    return u;
  }
  void apply_impulse_change(std::size_t k, const Vec3& delta) {
    const Contact& c = contacts[k];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    const Vec3 p = c.frame * delta;
    if (!model.is_fixed(b)) {
      velocity.linear[b] += model.inverse_mass[b] * p;
      velocity.angular[b] += inverse_inertia[b] * (levers(c.arm_b, c.frame) * delta);
    }
    if (!model.is_fixed(a)) {
      velocity.linear[a] -= model.inverse_mass[a] * p;
      velocity.angular[a] -= inverse_inertia[a] * (levers(c.arm_a, c.frame) * delta);
    }
  }
};

bool same_bits(const std::vector<Vec3>& x, const std::vector<Vec3>& y) {
  return x.size() == y.size() && std::memcmp(x.data(), y.data(), x.size() * sizeof(Vec3)) == 0;
}

/// The free velocities of the scene's next step: the state's, plus one step of gravity.
BodyVelocities free_velocities(const TestScene& s) {
  BodyVelocities free{s.state.velocity, s.state.angular_velocity};
  for (std::size_t b = 0; b < s.model.body_count(); ++b) {
    if (!s.model.is_fixed(b)) free.linear[b] += s.options.integrator.time_step * s.options.gravity.acceleration;
  }
  return free;
}

/// The frictional box after two steps, with the contacts of its third step (not yet prepared) and
/// that step's free velocities.
struct BoxStep {
  TestScene scene = packed_box(0.5, Vec3(0.05, -0.03, 0.02));
  ContactList contacts;
  BodyVelocities free;
  BoxStep() {
    scene.steps(2);
    contacts = scene.workspace.carry.contacts;
    free = free_velocities(scene);
  }
};

TEST(SweepPlan, ThreadedSweepsEqualASequentialGaussSeidelInPlanOrderBitForBit) {
  // This step's problem: the contacts at the current state, prepared from a free velocity.
  BoxStep box;
  const TestScene& s = box.scene;
  ContactList& prepared = box.contacts;
  const BodyVelocities& free = box.free;
  SolverOptions options;
  options.warm_start = false;  // impulses start at zero in both
  options.polish_after = 0;
  options.tolerance = 1e-300;  // never met: exactly max_iterations sweeps
  options.max_iterations = 25;
  options.relaxation = 1.0;  // the reference below sweeps plain Gauss-Seidel
  prepare_contacts(s.model, s.state, free, s.options.integrator, options, prepared);
  ASSERT_GT(prepared.size(), 3000u);

  const int previous = omp_get_max_threads();
  for (const int blocks : {1, 16}) {
    options.block_count = blocks;
    // Reference: plain sweeps in the plan's order.
    ContactList reference_contacts = prepared;
    BodyVelocities reference_velocity = free;
    ReferenceProblem reference{s.model, reference_contacts, reference_velocity, {}};
    for (std::size_t b = 0; b < s.model.body_count(); ++b) {
      reference.inverse_inertia.push_back(world_inverse_inertia(s.model, b, s.state.orientation[b]));
    }
    const SweepPlan plan = plan_sweep(s.model, s.state, prepared, blocks);
    for (int sweep = 0; sweep < options.max_iterations; ++sweep) {
      nlgs_sweep(reference, std::span<const std::size_t>(plan.order), 1.0);
    }
    for (const int threads : {1, 2}) {
      omp_set_num_threads(threads);
      ContactList contacts = prepared;
      BodyVelocities velocity = free;
      const SolverStats stats = solve_contacts(s.model, s.state, options, contacts, velocity);
      EXPECT_EQ(stats.iterations, options.max_iterations);
      // The box has open points within the alert distance, which the sweeps pass by once a visit
      // has left them open (CompactProblem::stays_open); the reference visits every one.
      EXPECT_GT(stats.passed_by, prepared.size());
      EXPECT_TRUE(same_bits(velocity.linear, reference_velocity.linear))
          << blocks << " blocks, " << threads << " threads";
      EXPECT_TRUE(same_bits(velocity.angular, reference_velocity.angular))
          << blocks << " blocks, " << threads << " threads";
      bool impulses_equal = true;
      for (std::size_t k = 0; k < contacts.size(); ++k) {
        impulses_equal = impulses_equal && std::memcmp(contacts[k].impulse.data(), reference_contacts[k].impulse.data(),
                                                       sizeof(Vec3)) == 0;
      }
      EXPECT_TRUE(impulses_equal) << blocks << " blocks, " << threads << " threads";
    }
  }
  omp_set_num_threads(previous);
}

// The bound behind the skipped visits (CompactProblem::stays_open), checked directly: after every
// sweep, each point the sweeps would pass by has r = 0 and a positive normal velocity, as a visit
// would find; and some points are passed by.
TEST(SweepPlan, PointsPassedByAreOpenAfterEverySweep) {
  BoxStep box;
  const SolverOptions defaults;
  prepare_contacts(box.scene.model, box.scene.state, box.free, box.scene.options.integrator, defaults, box.contacts);
  for (Contact& c : box.contacts) c.impulse = Vec3::Zero();
  const SweepPlan plan = plan_sweep(box.scene.model, box.scene.state, box.contacts, defaults.block_count);
  CompactProblem compact =
      gather_compact_problem(box.scene.model, box.scene.state, plan, box.contacts, box.free, false);
  std::vector<std::size_t> positions(compact.size());
  for (std::size_t p = 0; p < positions.size(); ++p) positions[p] = p;
  GroupSweeps groups;
  std::size_t passed_by = 0, checked = 0;
  for (int sweep = 0; sweep < 25; ++sweep) {
    passed_by += planned_sweep(compact, plan, positions, 1.0, false, groups).passed_by;
    for (std::size_t p = 0; p < compact.size(); ++p) {
      if (!compact.stays_open(p)) continue;
      ++checked;
      ASSERT_EQ(compact.points[p].impulse, Vec3::Zero()) << "point " << p << " after sweep " << sweep;
      ASSERT_GT(compact.local_velocity(p).x(), 0.0) << "point " << p << " after sweep " << sweep;
    }
  }
  EXPECT_GT(passed_by, compact.size());
  EXPECT_GT(checked, compact.size());
}

TEST(SweepPlan, RunsAreIdenticalOnOneAndTwoThreads) {
  const int previous = omp_get_max_threads();
  std::vector<State> finals;
  std::vector<int> sweeps;
  for (const int threads : {1, 2}) {
    omp_set_num_threads(threads);
    TestScene s = packed_box(0.5, Vec3(0.2, -0.1, 0.1));
    s.options.solver.max_iterations = 100;
    int total = 0;
    for (int k = 0; k < 6; ++k) total += s.advance().solver.iterations;
    finals.push_back(s.state);
    sweeps.push_back(total);
  }
  omp_set_num_threads(previous);
  EXPECT_EQ(sweeps[0], sweeps[1]);
  EXPECT_TRUE(same_bits(finals[0].position, finals[1].position));
  EXPECT_TRUE(same_bits(finals[0].velocity, finals[1].velocity));
  EXPECT_TRUE(same_bits(finals[0].angular_velocity, finals[1].angular_velocity));
}

// Reference: momentum balance. 1 152 spheres standing in columns at rest: over one step the floor's
// impulse equals the total weight times h, whatever the block count and thread count.
TEST(SweepPlan, BlockedSweepsConvergeOnColumnsAtRest) {
  const int previous = omp_get_max_threads();
  for (const int blocks : {1, 16}) {
    for (const int threads : {1, 2}) {
      omp_set_num_threads(threads);
      TestScene s = packed_box(0.5);
      s.options.solver.block_count = blocks;
      s.options.solver.tolerance = 1e-8;
      s.options.solver.max_iterations = 100000;
      s.options.solver.polish_after = 0;
      s.advance();
      EXPECT_TRUE(s.last_report.solver.converged)
          << s.last_report.solver.iterations << " sweeps, residual " << s.last_report.solver.residual;
      double floor_impulse = 0.0, weight = 0.0;
      for (std::size_t b = 1; b < s.model.body_count(); ++b) weight += s.model.mass[b] * 9.81;
      for (const Contact& c : s.workspace.carry.contacts) {
        if (c.id.body_a == 0 || c.id.body_b == 0) floor_impulse += (c.frame * c.impulse).z();
      }
      const double expected = weight * s.options.integrator.time_step;
      EXPECT_NEAR(floor_impulse, expected, 1e-6 * expected) << blocks << " blocks, " << threads << " threads";
    }
  }
  omp_set_num_threads(previous);
}

// Over-relaxation (SolverOptions::relaxation > 1; nlgs_solver/README.md, "Over-relaxation"):
// reference: momentum balance, as above, on the columns solved from zero impulses, whose load
// Gauss-Seidel carries down one layer a sweep.
struct ColumnSolve {
  int sweeps = 0;
  bool converged = false;
  double residual = 0.0;
  double floor_error = 0.0;  ///< |floor impulse - weight h| / (weight h)
};
ColumnSolve solve_columns(double relaxation, double tolerance) {
  TestScene s = packed_box(0.5);
  s.options.solver.relaxation = relaxation;
  s.options.solver.tolerance = tolerance;
  s.options.solver.max_iterations = 100000;
  s.options.solver.polish_after = 0;
  s.options.solver.warm_start = false;
  s.advance();
  double floor_impulse = 0.0, weight = 0.0;
  for (std::size_t b = 1; b < s.model.body_count(); ++b) weight += s.model.mass[b] * 9.81;
  for (const Contact& c : s.workspace.carry.contacts) {
    if (c.id.body_a == 0 || c.id.body_b == 0) floor_impulse += (c.frame * c.impulse).z();
  }
  const double expected = weight * s.options.integrator.time_step;
  return {s.last_report.solver.iterations, s.last_report.solver.converged, s.last_report.solver.residual,
          std::abs(floor_impulse - expected) / expected};
}

TEST(Relaxation, OverRelaxedSweepsCarryTheColumnsLoadInFewerSweeps) {
  const ColumnSolve plain = solve_columns(1.0, 1e-8);
  ASSERT_TRUE(plain.converged);
  EXPECT_LT(plain.floor_error, 1e-6);
  for (const double relaxation : {1.5, 1.7}) {
    for (const double tolerance : {1e-4, 1e-6, 1e-8}) {
      const ColumnSolve over = solve_columns(relaxation, tolerance);
      ASSERT_TRUE(over.converged) << "omega " << relaxation << ", tolerance " << tolerance;
      // The solve ends on a plain sweep: the end-of-step residual meets the tolerance itself.
      EXPECT_LE(over.residual, tolerance) << "omega " << relaxation;
      EXPECT_LT(over.floor_error, 300 * tolerance) << "omega " << relaxation << ", tolerance " << tolerance;
      if (tolerance == 1e-8) {
        EXPECT_LT(over.floor_error, 1e-6);
        // Measured: 392 plain sweeps, 124 at omega = 1.5, 50 at 1.7.
        EXPECT_LT(over.sweeps, plain.sweeps / 2)
            << "omega " << relaxation << ": " << over.sweeps << " against " << plain.sweeps;
      }
    }
  }
}

// omega close to 2 stalls (each point overshoots its neighbours' corrections); the schedule then
// falls back to plain sweeps after a window without progress, so the solve costs at most a few
// windows more than plain Gauss-Seidel and still meets its tolerance.
TEST(Relaxation, FallsBackToPlainSweepsWhereOverRelaxationStalls) {
  const ColumnSolve plain = solve_columns(1.0, 1e-8);
  const ColumnSolve stalled = solve_columns(1.99, 1e-8);
  ASSERT_TRUE(stalled.converged) << stalled.sweeps << " sweeps, residual " << stalled.residual;
  EXPECT_LE(stalled.residual, 1e-8);
  EXPECT_LT(stalled.floor_error, 1e-6);
  const int window = 20;  // RelaxationSchedule::window, sweeps without progress before the fall-back
  EXPECT_LE(stalled.sweeps, plain.sweeps + 3 * window) << stalled.sweeps << " against " << plain.sweeps;
}

}  // namespace
}  // namespace rubble
