// The step's contact problem as explicit data (polish.cpp, explicit_contact_problem, seen through
// SolverOptions::problem_observer): W and q against the closed form of a sphere on a floor, the
// simulation's own solution of a pile checked as a solution of the written problem by the FCLib
// measure, and the refusal of laws the explicit problem does not describe. Then the stalled
// cluster's polish (polish_stalled_cluster) on a scene too large for the whole polish.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <stdexcept>
#include <vector>

#include "core/polyhedron.hpp"
#include "nlgs_solver/local_problem.hpp"
#include "nlgs_solver/nlgs.hpp"

#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

/// Entry (row, column) of a CSR matrix (0 where not stored).
double entry(const SparseMatrix& W, int row, int column) {
  for (int e = W.row_start[static_cast<std::size_t>(row)]; e < W.row_start[static_cast<std::size_t>(row) + 1]; ++e) {
    if (W.column[static_cast<std::size_t>(e)] == column) return W.value[static_cast<std::size_t>(e)];
  }
  return 0.0;
}

/// The problems the observer saw, one per step.
std::vector<LocalProblem> observe(TestScene& s, int steps) {
  std::vector<LocalProblem> seen;
  s.options.solver.problem_observer = [&](const LocalProblem& problem) { seen.push_back(problem); };
  s.steps(steps);
  return seen;
}

// Reference: a sphere (mass m, radius r, I = 2/5 m r^2) at rest on a fixed floor, its contact
// arm -r n. Then W = diag(1/m, 1/m + r^2/I, 1/m + r^2/I) = diag(1, 3.5, 3.5)/m in the contact
// frame, and q = the free velocity's local components: gravity's -g h along the normal (the
// normal points from the floor, body a, up to the sphere, body b), 0 tangentially. Within 1e-12.
TEST(ExplicitContactProblem, SphereOnAFloorHasTheClosedFormDelassusAndFreeVelocity) {
  const double r = 0.1, g = 9.81;
  TestScene s(2500.0, 0.5, 0.0);
  s.uniform_gravity(g);
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  s.sphere(r, Vec3(0.0, 0.0, r));
  const std::vector<LocalProblem> seen = observe(s, 3);
  ASSERT_EQ(seen.size(), 3u);
  const LocalProblem& p = seen.back();
  ASSERT_EQ(p.contact_count(), 1u);
  const double m = 2500.0 * 4.0 / 3.0 * M_PI * r * r * r, h = s.options.integrator.time_step;
  EXPECT_NEAR(entry(p.W, 0, 0), 1.0 / m, 1e-12 / m);
  EXPECT_NEAR(entry(p.W, 1, 1), 3.5 / m, 1e-12 / m);
  EXPECT_NEAR(entry(p.W, 2, 2), 3.5 / m, 1e-12 / m);
  EXPECT_NEAR(entry(p.W, 0, 1), 0.0, 1e-12 / m);
  EXPECT_NEAR(entry(p.W, 1, 2), 0.0, 1e-12 / m);
  EXPECT_NEAR(p.q[0], -g * h, 1e-9 * g * h);  // the sphere at rest to 1e-9 after its first steps
  EXPECT_NEAR(p.q[1], 0.0, 1e-12);
  EXPECT_NEAR(p.q[2], 0.0, 1e-12);
  EXPECT_EQ(p.mu[0], 0.5);
}

// Reference: the simulation's own tight solve. Four spheres piled on a floor (9 contact points),
// solved by the simulation's NLGS to 1e-12; its impulses, read in the ContactList's order, must
// solve the written problem: FCLib error (natural map, ||F||/||q||) below 1e-9. A wrong W or q
// (a missing coupling, a sign, the scaled W of the polish) leaves an O(1) error.
TEST(ExplicitContactProblem, TheSimulationsSolutionSolvesTheWrittenProblem) {
  TestScene s(2500.0, 0.3, 0.0);
  s.uniform_gravity(9.81);
  s.options.solver.tolerance = 1e-12;
  s.options.solver.max_iterations = 100000;
  const double r = 0.1, circumradius = 2 * r / std::sqrt(3.0);
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  for (int k = 0; k < 3; ++k) {
    const double a = 2.0 * M_PI * k / 3.0;
    s.sphere(r, Vec3(circumradius * std::cos(a), circumradius * std::sin(a), r));
  }
  s.sphere(r, Vec3(0, 0, r + std::sqrt(4 * r * r - circumradius * circumradius)));
  const std::vector<LocalProblem> seen = observe(s, 20);
  const LocalProblem& p = seen.back();
  const ContactList& contacts = s.workspace.carry.contacts;
  ASSERT_EQ(p.contact_count(), contacts.size());
  ASSERT_EQ(contacts.size(), 9u);  // 3 on the floor, 3 between the base spheres, 3 under the top one
  std::vector<double> r_solution(3 * contacts.size());
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    for (int i = 0; i < 3; ++i) r_solution[3 * k + static_cast<std::size_t>(i)] = contacts[k].impulse[i];
  }
  EXPECT_LT(fclib_error(p, r_solution, local_velocities(p, r_solution)), 1e-9);
  // And the problem is not trivially solved: zero impulses leave the pile falling (error ~1).
  EXPECT_GT(fclib_error(p, std::vector<double>(r_solution.size(), 0.0), p.q), 0.1);
}

// Rolling resistance is not in the explicit problem (nor in FCLib's format): observing such a
// scene's problem is refused rather than written wrong.
TEST(ExplicitContactProblem, RollingResistanceIsRefused) {
  TestScene s(2500.0, 0.5, 0.0);
  ContactLaw law{0.5, 0.0};
  law.rolling_friction = 0.1;
  s.model.contact_laws.reset(1, law);
  s.uniform_gravity(9.81);
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  s.sphere(0.1, Vec3(0.0, 0.0, 0.1));
  s.options.solver.problem_observer = [](const LocalProblem&) {};
  EXPECT_THROW(s.steps(2), std::invalid_argument);
}

// A tower of five 5 cm cubes (mu = 0.5, four points a face: the tangential impulses are not unique
// and plain sweeps crawl, nlgs_solver/README.md, "The simulation's Newton polish") beside a bed of
// 576 spheres resting apart on the floor: 596 points, more than polish_max_contacts, so the whole
// problem is never polished. Without the cluster polish the tower's steps run to the sweep cap
// (checked, so that the scene does show the stall); with it every step converges within 200
// sweeps and the top cube stays within 1e-6 of its size over 200 steps. Tolerance 1e-6.
TEST(ClusterPolish, SolvesAStalledTowerBesideABedOfSpheres) {
  auto run = [](std::size_t cluster_polish_max_contacts) {
    TestScene s(2500.0, 0.5, 0.0);
    s.uniform_gravity(9.81);
    s.options.integrator.time_step = 1e-3;
    s.options.solver.tolerance = 1e-6;
    s.options.solver.max_iterations = 1000;
    s.options.solver.cluster_polish_max_contacts = cluster_polish_max_contacts;
    s.plane(Vec3::Zero(), Vec3::UnitZ());
    const double radius = 0.02;
    for (int i = 0; i < 24; ++i) {
      for (int j = 0; j < 24; ++j) s.sphere(radius, Vec3(0.5 + 0.05 * i, 0.05 * j, radius));
    }
    const double side = 0.05;
    int top = 0;
    for (int k = 0; k < 5; ++k) {
      top = add_polyhedron_grain(s.model, make_box_polyhedron(Vec3::Constant(side / 2)), 0);
      s.place(top, Vec3(0, 0, side * (k + 0.5)), Quat::Identity(), Vec3::Zero());
    }
    const Vec3 start = s.state.position[static_cast<std::size_t>(top)];
    struct Outcome {
      int worst_sweeps = 0, unconverged = 0, cluster_polishes = 0;
      double drift = 0.0;
    } out;
    for (int k = 0; k < 200; ++k) {
      const StepReport& report = s.advance();
      EXPECT_EQ(report.contacts, 596u) << "step " << k;  // 576 spheres + 4 points a face of 5 cubes
      out.worst_sweeps = std::max(out.worst_sweeps, report.solver.iterations);
      out.unconverged += report.solver.converged ? 0 : 1;
      out.cluster_polishes += report.solver.cluster_polishes;
    }
    out.drift = (s.state.position[static_cast<std::size_t>(top)] - start).norm() / side;
    return out;
  };
  const auto sweeps_alone = run(0);
  EXPECT_EQ(sweeps_alone.cluster_polishes, 0);
  EXPECT_EQ(sweeps_alone.worst_sweeps, 1000);  // the stall this polish is for
  const auto polished = run(SolverOptions{}.cluster_polish_max_contacts);
  std::cout << "tower beside 576 spheres: worst sweeps " << sweeps_alone.worst_sweeps << " -> " << polished.worst_sweeps
            << ", unconverged steps " << sweeps_alone.unconverged << " -> " << polished.unconverged
            << ", cluster polishes " << polished.cluster_polishes << ", top drift " << sweeps_alone.drift << " -> "
            << polished.drift << " of its size\n";
  EXPECT_GT(polished.cluster_polishes, 0);
  EXPECT_EQ(polished.unconverged, 0);
  EXPECT_LE(polished.worst_sweeps, 200);
  EXPECT_LT(polished.drift, 1e-6);
}

}  // namespace
}  // namespace rubble
