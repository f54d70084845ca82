// Tests of simulation/run_control.cpp: the scene scales and automatic time step against hand
// computations, the rest detector on synthetic energy histories, the ETA.
#include "simulation/run_control.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

namespace rubble {
namespace {

/// Two spheres of radius 1 and 2 (density 1000) at x = -10 and x = +10, at rest.
void two_spheres(Model& model, State& state) {
  model.materials.push_back(Material{"rock", 1000.0});
  add_sphere(model, 1.0, 0);
  add_sphere(model, 2.0, 0);
  state.resize(2);
  state.position[0] = Vec3(-10.0, 0.0, 0.0);
  state.position[1] = Vec3(10.0, 0.0, 0.0);
}

TEST(SceneScales, SelfGravityFromHandComputation) {
  Model model;
  State state;
  two_spheres(model, state);
  GravitySettings gravity;
  gravity.kind = GravitySettings::Kind::self;
  const SceneScales s = scene_scales(model, state, gravity);
  const double m1 = 1000.0 * 4.0 / 3.0 * std::numbers::pi;
  const double m2 = 8.0 * m1;
  const double M = m1 + m2;
  const double x_cm = (-10.0 * m1 + 10.0 * m2) / M;
  // R = max(|x_i - x_cm| + r_i): grain 0 is 10 + x_cm + 1 away.
  const double R = std::max(10.0 + x_cm + 1.0, 10.0 - x_cm + 2.0);
  EXPECT_EQ(s.grains, 2u);
  EXPECT_NEAR(s.total_mass, M, 1e-9 * M);
  EXPECT_NEAR(s.cloud_radius, R, 1e-12 * R);
  EXPECT_EQ(s.min_diameter, 2.0);
  EXPECT_NEAR(s.mean_density, 1000.0, 1e-9);
  EXPECT_NEAR(s.reference_velocity, std::sqrt(2.0 * 6.674e-11 * M / R), 1e-12);
  EXPECT_NEAR(s.characteristic_time, 1.0 / std::sqrt(6.674e-11 * 1000.0), 1e-6);
  // dt = min(0.01 d_min / v, 0.01 T): here the travel bound (v is tiny, T is 1.2e4 s).
  const TimeStepChoice choice = automatic_time_step(model, state, gravity);
  EXPECT_NEAR(choice.time_step, std::min(0.02 / s.reference_velocity, 0.01 * s.characteristic_time), 1e-12);
  EXPECT_EQ(choice.rule, 0.02 / s.reference_velocity < 0.01 * s.characteristic_time ? "travel" : "time");
}

TEST(SceneScales, UniformGravityAndNoGravity) {
  Model model;
  State state;
  two_spheres(model, state);
  state.position[1] = Vec3(10.0, 0.0, 5.0);  // 5 m higher
  GravitySettings gravity;
  gravity.kind = GravitySettings::Kind::uniform;
  gravity.acceleration = Vec3(0.0, 0.0, -9.81);
  // H = 5 (height of the centres along g) + d_min 2 = 7: v = sqrt(2 g H), T = sqrt(2 H / g).
  SceneScales s = scene_scales(model, state, gravity);
  EXPECT_NEAR(s.reference_velocity, std::sqrt(2.0 * 9.81 * 7.0), 1e-12);
  EXPECT_NEAR(s.characteristic_time, std::sqrt(2.0 * 7.0 / 9.81), 1e-12);
  EXPECT_NEAR(automatic_time_step(model, state, gravity).time_step, 0.01 * 2.0 / std::sqrt(2.0 * 9.81 * 7.0), 1e-15);
  // No gravity: the initial speed sets the scale; at rest there is none.
  gravity.kind = GravitySettings::Kind::none;
  EXPECT_THROW(automatic_time_step(model, state, gravity), std::invalid_argument);
  EXPECT_THROW(automatic_rest_criterion(scene_scales(model, state, gravity)), std::invalid_argument);
  state.velocity[0] = Vec3(0.0, 4.0, 0.0);
  s = scene_scales(model, state, gravity);
  EXPECT_EQ(s.reference_velocity, 4.0);
  EXPECT_NEAR(automatic_time_step(model, state, gravity).time_step, 0.01 * 2.0 / 4.0, 1e-15);
}

TEST(AutomaticRestCriterion, FractionsOfTheReferenceEnergyAndTime) {
  SceneScales s;
  s.mean_mass = 2.0;
  s.reference_velocity = 3.0;
  s.characteristic_time = 100.0;
  const RestCriterion automatic = automatic_rest_criterion(s);
  EXPECT_DOUBLE_EQ(automatic.mean_kinetic_energy, auto_rest_energy_fraction * 0.5 * 2.0 * 9.0);
  EXPECT_DOUBLE_EQ(automatic.duration, auto_rest_duration_fraction * 100.0);
  s.has_polyhedra = true;
  EXPECT_DOUBLE_EQ(automatic_rest_criterion(s).mean_kinetic_energy,
                   auto_rest_energy_fraction_polyhedra * 0.5 * 2.0 * 9.0);
  const RestCriterion given = automatic_rest_criterion(s, 0.5, 7.0);
  EXPECT_EQ(given.mean_kinetic_energy, 0.5);
  EXPECT_EQ(given.duration, 7.0);
}

TEST(RestDetector, StartingAtRestIsNotRestAndRestNeedsTheDuration) {
  RestDetector detector;
  detector.criterion = RestCriterion{1.0, 10.0};
  // At rest from the start: never "at rest" before the energy has risen.
  for (int t = 0; t < 100; ++t) EXPECT_FALSE(detector.update(t, 0.0));
  EXPECT_FALSE(detector.armed);
  EXPECT_FALSE(detector.update(100.0, 50.0));
  EXPECT_TRUE(detector.armed);
  // Below from t = 101 on: rest at t = 111, not before; a rise in between resets the clock.
  EXPECT_FALSE(detector.update(101.0, 0.5));
  EXPECT_FALSE(detector.update(105.0, 0.5));
  EXPECT_FALSE(detector.update(106.0, 2.0));
  EXPECT_FALSE(detector.update(107.0, 0.5));
  EXPECT_FALSE(detector.update(116.5, 0.5));
  EXPECT_TRUE(detector.update(117.0, 0.5));
}

// An exact exponential decay E = 1000 exp(-t/50) from t = 0: the threshold 1 is crossed at
// t* = 50 ln 1000 = 345.4; with a duration 20, rest at 365.4. The estimate made at t = 150 must
// say so (to 1 s: the history is an exact exponential).
TEST(RestDetector, EstimatesTheRestTimeFromAnExponentialDecay) {
  RestDetector detector;
  detector.criterion = RestCriterion{1.0, 20.0};
  detector.decay_window = 50.0;
  EXPECT_FALSE(detector.estimated_rest_time().has_value());
  for (double t = 0.0; t <= 150.0; t += 0.5) detector.update(t, 1000.0 * std::exp(-t / 50.0));
  ASSERT_TRUE(detector.estimated_rest_time().has_value());
  EXPECT_NEAR(*detector.estimated_rest_time(), 50.0 * std::log(1000.0) + 20.0, 1.0);
  // A rising energy has no estimate.
  RestDetector rising;
  rising.criterion = RestCriterion{1.0, 20.0};
  for (double t = 0.0; t <= 10.0; t += 0.5) rising.update(t, 2.0 + t);
  EXPECT_FALSE(rising.estimated_rest_time().has_value());
}

TEST(EtaSeconds, FromTheSimulatedTimeRate) {
  EXPECT_DOUBLE_EQ(eta_seconds(10.0, 0.0, 100.0, 400.0), 30.0);  // 10 s wall per 100 s simulated
  EXPECT_DOUBLE_EQ(eta_seconds(10.0, 50.0, 100.0, 100.0), 0.0);
  EXPECT_LT(eta_seconds(0.0, 0.0, 0.0, 100.0), 0.0);
}

// The step-count bound that holds [time] end_time and --end-time alike: 10^12 steps of 1e-4 s is
// 1e8 s; one step more is refused, as are non-finite and sub-step end times.
TEST(EndTimeProblem, BoundsTheStepCount) {
  EXPECT_FALSE(end_time_problem(1e8, 0.0, 1e-4).has_value());
  EXPECT_FALSE(end_time_problem(1e-4, 0.0, 1e-4).has_value());
  EXPECT_TRUE(end_time_problem(1e8 * (1.0 + 1e-12), 0.0, 1e-4).has_value());
  EXPECT_TRUE(end_time_problem(1e9, 0.0, 1e-4).has_value());
  EXPECT_TRUE(end_time_problem(1e308, 0.0, 1e-4).has_value());
  EXPECT_TRUE(end_time_problem(std::numeric_limits<double>::infinity(), 0.0, 1e-4).has_value());
  EXPECT_TRUE(end_time_problem(std::nan(""), 0.0, 1e-4).has_value());
  EXPECT_TRUE(end_time_problem(0.5e-4, 0.0, 1e-4).has_value());
  // Counted from the start time: 10^12 steps after t = 1e8 s is fine up to 2e8 s.
  EXPECT_FALSE(end_time_problem(1.9e8, 1e8, 1e-4).has_value());
}

}  // namespace
}  // namespace rubble
