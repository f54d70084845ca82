// Polyhedra in motion through the full step (detection + NLGS + integrator): rest on a face,
// the incline (stick / slide at a = g (sin a - mu cos a)), a tower, an edge-edge impact and a pour.
#include <gtest/gtest.h>

#include <iostream>

#include <cmath>
#include <random>

#include "core/polyhedron.hpp"
#include "preprocessing/random_polyhedron.hpp"
#include "support/polyhedra_pour.hpp"
#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

constexpr double g = 9.81;

int add_cube(TestScene& s, double side, const Vec3& position, const Quat& orientation = Quat::Identity()) {
  const int id = add_polyhedron_grain(s.model, make_box_polyhedron(Vec3::Constant(side / 2)), 0);
  s.place(id, position, orientation, Vec3::Zero());
  return id;
}

double max_angular_speed(const State& state, int body) {
  return state.angular_velocity[static_cast<std::size_t>(body)].norm();
}

// A 10 cm cube set exactly on a floor: 3 or 4 contact points every step, no rotation
// (|w| < 1e-8 rad/s) and no drift over 10^4 steps.
TEST(PolyhedraDynamics, CubeRestsOnAFaceWithoutRocking) {
  TestScene s(2500.0, 0.5, 0.0);
  s.uniform_gravity(g);
  s.options.integrator.time_step = 1e-3;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  const int cube = add_cube(s, 0.1, Vec3(0.01, -0.02, 0.05));
  double worst_spin = 0.0;
  for (int k = 0; k < 10000; ++k) {
    const StepReport& report = s.advance();
    ASSERT_GE(report.contacts, 3u) << "step " << k;
    ASSERT_LE(report.contacts, 4u) << "step " << k;
    worst_spin = std::max(worst_spin, max_angular_speed(s.state, cube));
  }
  EXPECT_LT(worst_spin, 1e-8);
  EXPECT_NEAR(s.state.position[static_cast<std::size_t>(cube)].z(), 0.05, 1e-6);
  EXPECT_LT((s.state.position[static_cast<std::size_t>(cube)].head<2>() - Eigen::Vector2d(0.01, -0.02)).norm(), 1e-9);
}

/// A cube on a plane inclined by `alpha` about x (downhill along -y), starting at rest;
/// returns the downhill velocity after `time` and the largest angular speed seen.
std::pair<double, double> slide(double alpha, double mu, double time) {
  TestScene s(2500.0, mu, 0.0);
  s.uniform_gravity(g);
  s.options.integrator.time_step = 1e-3;
  const Quat tilt(Eigen::AngleAxisd(alpha, Vec3::UnitX()));
  const Vec3 normal = tilt * Vec3::UnitZ();
  s.plane(Vec3::Zero(), normal);
  const int cube = add_cube(s, 0.1, 0.05 * normal, tilt);
  double spin = 0.0;
  s.steps(static_cast<long>(std::lround(time / s.options.integrator.time_step)));
  spin = std::max(spin, max_angular_speed(s.state, cube));
  const Vec3 downhill = -(tilt * Vec3::UnitY());
  return {s.state.velocity[static_cast<std::size_t>(cube)].dot(downhill), spin};
}

// Reference: a block on an incline sticks when tan(alpha) < mu and otherwise slides with
// a = g (sin alpha - mu cos alpha); it never rolls (the base is wide). Tolerance 1%.
TEST(PolyhedraDynamics, CubeOnAnInclineSticksOrSlidesNeverRolls) {
  const auto [v_stick, spin_stick] = slide(20.0 * M_PI / 180.0, 0.5, 0.5);  // tan 20 deg = 0.36 < 0.5
  EXPECT_LT(std::abs(v_stick), 1e-8);
  EXPECT_LT(spin_stick, 1e-6);
  const double alpha = 30.0 * M_PI / 180.0, mu = 0.3;
  const double time = 0.5;
  const auto [v_slide, spin_slide] = slide(alpha, mu, time);
  const double expected = g * (std::sin(alpha) - mu * std::cos(alpha)) * time;
  EXPECT_NEAR(v_slide, expected, 0.01 * expected);
  EXPECT_LT(spin_slide, 1e-6);
}

// A tower of 10 cubes (5 cm) on a floor, mu = 0.5: after 10^4 steps the top cube has moved by
// less than 1e-6 of its size. With four points per face the tangential impulses are not unique
// and plain sweeps crawl (10^3-10^4 a step, tests/stability); the Newton polish
// (SolverOptions::polish_after) solves each step in a few dozen sweeps. The drift is the solver's
// residual integrated over the steps, since no velocity-level overlap correction pulls the stack
// back any more (nlgs_solver/overlap_recovery.hpp). The residual is relative to the impulses'
// velocity changes (nlgs_solver/README.md), which in a stack are ~10x the free velocities of the
// floor contacts: measured drift 2.9e-7 m at tolerance 1e-7, 3.1e-8 m at 1e-8 (5.7 s CPU).
TEST(PolyhedraDynamics, TowerOfTenCubesStaysPut) {
  TestScene s(2500.0, 0.5, 0.0);
  s.uniform_gravity(g);
  s.options.integrator.time_step = 1e-3;
  s.options.solver.tolerance = 1e-8;
  s.options.solver.max_iterations = 1000;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  const double side = 0.05;
  int top = 0;
  for (int k = 0; k < 10; ++k) top = add_cube(s, side, Vec3(0, 0, side * (k + 0.5)));
  const Vec3 start = s.state.position[static_cast<std::size_t>(top)];
  int worst_sweeps = 0;
  for (int k = 0; k < 10000; ++k) {
    const StepReport& report = s.advance();
    ASSERT_EQ(report.contacts, 40u) << "step " << k;  // 4 points per face, every step
    worst_sweeps = std::max(worst_sweeps, report.solver.iterations);
  }
  const Vec3 drift = s.state.position[static_cast<std::size_t>(top)] - start;
  std::cout << "tower of 10 cubes: top drift (" << drift.transpose() << ") m, worst sweeps " << worst_sweeps << "\n";
  EXPECT_LT(drift.norm(), 1e-6 * side);
  EXPECT_LT(worst_sweeps, 1000);
}

// A regular tetrahedron falls edge-down onto the upturned edge of a fixed one, the two edges
// crossed at right angles: the first contact is edge-edge (1 point, edge features on both
// sides), and no interpenetration ever exceeds 1e-3 d.
TEST(PolyhedraDynamics, TetrahedronEdgeOnEdge) {
  TestScene s(2500.0, 0.3, 0.0);
  s.uniform_gravity(g);
  s.options.integrator.time_step = 2e-4;
  const double a = 0.1;  // edge
  const double h = a / std::sqrt(2.0) / 2.0;
  // Alternate corners of a cube: top edge along (1,1,0) at z = h, bottom edge along (1,-1,0).
  std::vector<Vec3> v = {{h, h, h}, {h, -h, -h}, {-h, h, -h}, {-h, -h, h}};
  std::vector<std::vector<int>> f = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
  const ConvexPolyhedron tetra = make_convex_polyhedron(v, f);
  const double d = 2.0 * tetra.bounding_radius;
  const int below = add_polyhedron_grain(s.model, tetra, 0);
  const int above = add_polyhedron_grain(s.model, tetra, 0);
  // The lower one is held fixed (infinite mass), like a wall.
  s.model.inverse_mass[static_cast<std::size_t>(below)] = 0.0;
  s.model.inverse_inertia[static_cast<std::size_t>(below)] = Vec3::Zero();
  s.place(below, Vec3::Zero(), Quat::Identity(), Vec3::Zero());
  s.place(above, Vec3(0.003, -0.002, 2 * h + 0.005), Quat::Identity(), Vec3::Zero());
  bool first = true;
  double deepest = 0.0;
  for (int k = 0; k < 1500; ++k) {
    s.advance();
    for (const Contact& c : s.workspace.carry.contacts) {
      deepest = std::max(deepest, -c.gap);
    }
    if (first && !s.workspace.carry.contacts.empty()) {
      first = false;
      ASSERT_EQ(s.workspace.carry.contacts.size(), 1u);
      EXPECT_EQ(s.workspace.carry.contacts[0].id.feature_a >> 30, 1u);  // edge
      EXPECT_EQ(s.workspace.carry.contacts[0].id.feature_b >> 30, 1u);  // edge
      EXPECT_NEAR((s.workspace.carry.contacts[0].frame.col(0) - Vec3::UnitZ()).norm(), 0.0, 1e-6);
    }
  }
  EXPECT_FALSE(first);
  EXPECT_LT(deepest, 1e-3 * d);
}

/// 200 random polyhedra (d = 10 cm, 10-20 vertices to keep the test short) in a 7 x 7 grid of
/// layers above a floor inside 4 plane walls, poured under gravity with mu = 0.5, e = 0, for
/// `steps` steps of `time_step` (alert distance 0.1 d). Returns the peak and final kinetic
/// energies and the deepest grain-grain overlap seen.
struct PourResult {
  double peak = 0.0, last = 0.0, deepest = 0.0, d = 0.1;
};
PourResult pour(long steps, double time_step) {
  TestScene s(2500.0, 0.5, 0.0);
  s.uniform_gravity(g);
  s.options.integrator.time_step = time_step;
  PourResult result;
  const double d = result.d;
  s.options.detection.alert_distance = 0.1 * d;
  s.options.solver.tolerance = 1e-3;
  s.options.solver.max_iterations = 300;
  testing::add_polyhedra_pour(s, 200, d, 0, 7);
  auto kinetic_energy = [&] {
    double e = 0.0;
    for (std::size_t b = 0; b < s.model.body_count(); ++b) {
      if (s.model.is_fixed(b)) continue;
      const Mat3 r = s.state.orientation[b].toRotationMatrix();
      const Vec3 w = r.transpose() * s.state.angular_velocity[b];
      e += 0.5 * s.model.mass[b] * s.state.velocity[b].squaredNorm() +
           0.5 * w.dot(s.model.principal_inertia[b].cwiseProduct(w));
    }
    return e;
  };
  for (long k = 0; k < steps; ++k) {
    s.advance();
    for (const Contact& c : s.workspace.carry.contacts) {
      if (s.model.is_grain(c.id.body_a) && s.model.is_grain(c.id.body_b))
        result.deepest = std::max(result.deepest, -c.gap);
    }
    result.last = kinetic_energy();
    result.peak = std::max(result.peak, result.last);
  }
  return result;
}

// The targets: the kinetic energy falls by 6 orders of magnitude from its peak and no
// pair ever overlaps by more than 1% of d. The step must resolve the motion: the top layer lands
// at ~3 m/s, i.e. 1.5% of d per step at h = 5e-4 s, and a vertex sliding under the edge of a facet
// within one step (contact points are found at the start of the step) then sinks by up to ~1.3% d;
// at h = 2.5e-4 s the deepest overlap measured is 0.33% d and KE/peak = 8e-8 after 3 s
// (a few grains topple late, at 1.7-2 s, so the pile needs the full 3 s).
TEST(PolyhedraDynamics, TwoHundredPolyhedraPouredIntoABoxComeToRest) {
  const PourResult r = pour(12000, 2.5e-4);
  EXPECT_LT(r.deepest, 0.01 * r.d);
  EXPECT_LT(r.last, 1e-6 * r.peak) << "peak " << r.peak << " J, last " << r.last << " J";
}

// The failure mode at twice the step: the same pour at h = 5e-4 s overlaps far more during the
// impacts (measured 1.3% d, against 0.33% d above). Asserted (> 0.5% d) so that a change which
// makes the large step safe (e.g. swept contact points) shows up here.
TEST(PolyhedraDynamics, TwoHundredPolyhedraAtTwiceTheStepOverlapMore) {
  const PourResult r = pour(1200, 5e-4);
  EXPECT_GT(r.deepest, 0.005 * r.d);
  EXPECT_LT(r.deepest, 0.03 * r.d);
}

}  // namespace
}  // namespace rubble
