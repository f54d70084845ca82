// The simulation's NLGS on small sphere packings: equilibrium against momentum balance, the
// reported residual, warm start.
#include <gtest/gtest.h>

#include <cmath>

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
  ASSERT_TRUE(s.last_report.solver.converged) << "residual " << s.last_report.solver.residual << " after "
                                              << s.last_report.solver.iterations << " sweeps";
  double floor_impulse = 0.0;
  double weight = 0.0;
  for (std::size_t b = 1; b < s.model.body_count(); ++b) weight += s.model.mass[b] * 9.81;
  for (const Contact& c : s.workspace.contacts) {
    if (c.id.body_a == 0 || c.id.body_b == 0) floor_impulse += (c.frame * c.impulse).z();
  }
  // Momentum balance over one step with the pile at rest: floor impulse = total weight * h.
  EXPECT_NEAR(floor_impulse, weight * s.options.integrator.time_step, 1e-7 * weight * s.options.integrator.time_step);
  // And every contact honours Coulomb's cone.
  for (const Contact& c : s.workspace.contacts) {
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

}  // namespace
}  // namespace rubble
