// Self-gravity coupled to contacts: a cold collapse of 10^3 spheres (the accretion study's
// cloud, the LMGC90 accretion paper) in which contacts (e_n = 0) can only dissipate, so the total energy
// (kinetic + gravitational, the latter by an exact direct sum) must never grow.
#include <gtest/gtest.h>

#include <random>

#include "support/test_scene.hpp"

namespace rubble {
namespace {

double gravitational_energy(const Model& model, const State& state, double G) {
  double energy = 0.0;
  for (std::size_t i = 0; i < model.body_count(); ++i)
    for (std::size_t j = i + 1; j < model.body_count(); ++j)
      energy -= G * model.mass[i] * model.mass[j] / (state.position[i] - state.position[j]).norm();
  return energy;
}

double kinetic_energy(const Model& model, const State& state) {
  double energy = 0.0;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    const Mat3 R = state.orientation[b].toRotationMatrix();
    const Vec3 w = R.transpose() * state.angular_velocity[b];
    energy +=
        0.5 * model.mass[b] * state.velocity[b].squaredNorm() + 0.5 * w.dot(model.principal_inertia[b].cwiseProduct(w));
  }
  return energy;
}

TEST(SelfGravity, ColdCollapseNeverGainsEnergy) {
  testing::TestScene s(5164.0, 0.0, 0.0);  // the study's density, mu = 0, e_n = 0
  s.options.gravity.kind = GravitySettings::Kind::self;
  s.options.gravity.self_gravity.method = gravity::Method::direct;
  const double G = s.options.gravity.self_gravity.G;
  s.options.integrator.time_step = 1.0;  // s; free-fall time ~ 920 s
  s.options.solver.tolerance = 1e-6;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double cell = 10.0;  // d_max
  for (int x = 0; x < 10; ++x)
    for (int y = 0; y < 10; ++y)
      for (int z = 0; z < 10; ++z) {
        const double radius = 0.5 * (7.5 + 2.5 * unit(rng));
        const double room = 0.5 * cell - radius;
        s.sphere(radius, Vec3(cell * x + room * (2 * unit(rng) - 1), cell * y + room * (2 * unit(rng) - 1),
                              cell * z + room * (2 * unit(rng) - 1)));
      }
  const double initial = gravitational_energy(s.model, s.state, G);
  double previous = initial;
  double peak_kinetic = 0.0;
  int contacts_seen = 0;
  for (int block = 0; block < 24; ++block) {
    s.steps(50);
    contacts_seen = std::max(contacts_seen, static_cast<int>(s.last_report.contacts));
    const double kinetic = kinetic_energy(s.model, s.state);
    const double total = kinetic + gravitational_energy(s.model, s.state, G);
    peak_kinetic = std::max(peak_kinetic, kinetic);
    // Allowed growth per 50 steps: the solver tolerance times the energy scale.
    EXPECT_LE(total, previous + 1e-6 * std::abs(initial)) << "t = " << s.state.time << " s";
    previous = std::min(previous, total);
  }
  EXPECT_GT(contacts_seen, 500);                      // the cloud did collapse into contact
  EXPECT_GT(peak_kinetic, 1e-3 * std::abs(initial));  // and fell
  EXPECT_LT(previous, initial);                       // contacts dissipated
}

}  // namespace
}  // namespace rubble
