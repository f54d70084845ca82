// Anderson acceleration of the sweeps (nlgs_solver/anderson.cpp), on a stack that Gauss-Seidel
// alone settles slowly: the same solution to the tolerance in fewer sweeps, and the same bits for
// one and two threads.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cstring>
#include <iostream>
#include <vector>

#include "nlgs_solver/nlgs.hpp"
#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

/// What a run of the stack gives: its sweeps, its worst step, the floor's normal impulse summed
/// over the last step, and the final positions.
struct StackRun {
  int sweeps = 0, worst_sweeps = 0, unconverged = 0;
  double floor_impulse = 0.0, weight_impulse = 0.0;
  std::vector<Vec3> positions;
};

/// 8 x 8 x 8 spheres of 1 cm stacked in columns on the floor, a hair apart, mu = 0.3: the load
/// reaches the floor through eight layers, which plain sweeps carry down one layer a sweep.
StackRun run_stack(int anderson_depth, double relaxation, int threads) {
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
  TestScene s(2500.0, 0.3, 0.0);
  s.uniform_gravity(9.81);
  s.options.integrator.time_step = 1e-3;
  s.options.solver.tolerance = 1e-6;
  s.options.solver.max_iterations = 2000;
  s.options.solver.relaxation = relaxation;
  s.options.solver.anderson_depth = anderson_depth;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  const double radius = 0.01;
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) {
      for (int k = 0; k < 8; ++k) {
        s.sphere(radius, Vec3(2.0001 * radius * i, 2.0001 * radius * j, radius * (1.0001 + 2.0001 * k)));
      }
    }
  }
  StackRun out;
  for (int step = 0; step < 30; ++step) {
    const StepReport& report = s.advance();
    out.sweeps += report.solver.iterations;
    out.worst_sweeps = std::max(out.worst_sweeps, report.solver.iterations);
    out.unconverged += report.solver.converged ? 0 : 1;
  }
  double mass = 0.0;
  for (std::size_t b = 0; b < s.model.body_count(); ++b)
    mass += s.model.is_fixed(b) ? 0.0 : 1.0 / s.model.inverse_mass[b];
  out.weight_impulse = mass * 9.81 * s.options.integrator.time_step;
  for (const Contact& c : s.workspace.carry.contacts) {
    if (s.model.is_fixed(c.id.body_a) || s.model.is_fixed(c.id.body_b)) out.floor_impulse += (c.frame * c.impulse).z();
  }
  out.positions = s.state.position;
  omp_set_num_threads(saved);
  return out;
}

TEST(Anderson, SettlesAStackInFewerSweepsToTheSameSolution) {
  for (const double relaxation : {1.0, 1.5}) {
    const StackRun alone = run_stack(0, relaxation, 1);
    const StackRun mixed = run_stack(5, relaxation, 1);
    std::cout << "512-sphere stack, omega " << relaxation << ": sweeps " << alone.sweeps << " -> " << mixed.sweeps
              << " (worst step " << alone.worst_sweeps << " -> " << mixed.worst_sweeps << "), floor impulse / weight "
              << alone.floor_impulse / alone.weight_impulse << ", " << mixed.floor_impulse / mixed.weight_impulse
              << "\n";
    EXPECT_EQ(alone.unconverged, 0);
    EXPECT_EQ(mixed.unconverged, 0);
    EXPECT_LT(mixed.sweeps, 0.7 * alone.sweeps) << "omega " << relaxation;
    // At rest the floor carries the weight: both to the tolerance's order.
    EXPECT_NEAR(mixed.floor_impulse / mixed.weight_impulse, 1.0, 1e-4);
    EXPECT_NEAR(alone.floor_impulse / alone.weight_impulse, 1.0, 1e-4);
    double largest = 0.0;
    for (std::size_t b = 0; b < alone.positions.size(); ++b) {
      largest = std::max(largest, (alone.positions[b] - mixed.positions[b]).norm());
    }
    EXPECT_LT(largest, 1e-7) << "m";  // of 1 cm spheres: the two solves differ by the tolerance only
  }
}

TEST(Anderson, SameBitsForOneAndTwoThreads) {
  const StackRun one = run_stack(5, 1.5, 1);
  const StackRun two = run_stack(5, 1.5, 2);
  ASSERT_EQ(one.positions.size(), two.positions.size());
  EXPECT_EQ(std::memcmp(one.positions.data(), two.positions.data(), one.positions.size() * sizeof(Vec3)), 0);
  EXPECT_EQ(one.sweeps, two.sweeps);
}

}  // namespace
}  // namespace rubble
