// Tests of simulation/run_control.cpp: the scene scales and automatic time step against hand
// computations, the rest detector on synthetic energy histories, the ETA.
#include "simulation/run_control.hpp"

#include <gtest/gtest.h>

#include <algorithm>
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
  EXPECT_EQ(s.rest_reference_velocity, s.reference_velocity);
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
  // The rest speed's scale under uniform gravity: a fall over the smallest grain, sqrt(g d_min).
  EXPECT_NEAR(s.rest_reference_velocity, std::sqrt(9.81 * 2.0), 1e-12);
  EXPECT_NEAR(automatic_rest_criterion(s).speed, 0.05 * std::sqrt(9.81 * 2.0), 1e-12);
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

TEST(AutomaticRestCriterion, FractionsOfTheReferenceSpeedAndTime) {
  SceneScales s;
  s.mean_mass = 2.0;
  s.reference_velocity = 3.0;
  s.rest_reference_velocity = 3.0;
  s.characteristic_time = 100.0;
  const RestCriterion automatic = automatic_rest_criterion(s);
  EXPECT_DOUBLE_EQ(automatic.speed, 0.05 * 3.0);
  EXPECT_DOUBLE_EQ(automatic.duration, 0.5 * 100.0);
  EXPECT_EQ(automatic.quantile, 0.99);
  EXPECT_EQ(automatic.coordination_change, 0.05);  // no grain count: the value at 1000 grains
  s.grains = 250;
  EXPECT_DOUBLE_EQ(automatic_rest_criterion(s).coordination_change, 0.1);  // 0.05 sqrt(1000 / 250)
  EXPECT_EQ(automatic_rest_criterion(s, 0.0, 0.0, 0.125).coordination_change, 0.125);
  EXPECT_EQ(automatic.contact_change, 0.2);
  const RestCriterion given = automatic_rest_criterion(s, 0.5, 7.0);
  EXPECT_EQ(given.speed, 0.5);
  EXPECT_EQ(given.duration, 7.0);
}

/// A sample at `time` with speed quantile `speed`, Z `z` and contact pairs {(0, k) : k < pairs}.
RestSample sample(double time, double speed, double z = 4.0, std::uint32_t pairs = 100) {
  RestSample s;
  s.time = time;
  s.speed = speed;
  s.coordination = z;
  s.grains = 1000;
  for (std::uint32_t k = 1; k <= pairs; ++k) s.pairs.emplace_back(0, k);
  return s;
}

TEST(RestDetector, StartingAtRestIsNotRestAndRestNeedsTheDuration) {
  RestDetector detector;
  detector.criterion = RestCriterion{1.0, 0.99, 0.05, 0.2, 10.0};
  // At rest from the start: never "at rest" before the speed has risen.
  for (int t = 0; t < 100; ++t) EXPECT_FALSE(detector.update(sample(t, 0.0)));
  EXPECT_FALSE(detector.armed);
  EXPECT_FALSE(detector.update(sample(100.0, 50.0)));
  EXPECT_TRUE(detector.armed);
  // Slow from t = 101 on: rest at t = 111, not before; a faster step in between resets the clock.
  EXPECT_FALSE(detector.update(sample(101.0, 0.5)));
  EXPECT_FALSE(detector.update(sample(105.0, 0.5)));
  EXPECT_FALSE(detector.update(sample(106.0, 2.0)));
  EXPECT_EQ(detector.last_failure, RestCondition::speed);
  EXPECT_FALSE(detector.update(sample(107.0, 0.5)));
  EXPECT_FALSE(detector.update(sample(116.5, 0.5)));
  EXPECT_TRUE(detector.update(sample(117.0, 0.5)));
}

// Slow grains are not at rest while the aggregate still compacts (Z rises) or rearranges (the
// contacts change at constant Z): issue 18's aggregates kept compacting after the old criterion.
TEST(RestDetector, ZAndContactChangesHoldRestUp) {
  RestDetector detector;
  detector.criterion = RestCriterion{1.0, 0.99, 0.05, 0.2, 10.0};
  detector.armed = true;
  // Z creeps by 0.01 per s: the window restarts every time it has moved by more than 0.05.
  double z = 4.0;
  for (double t = 0.0; t <= 30.0; t += 1.0, z += 0.01) EXPECT_FALSE(detector.update(sample(t, 0.5, z))) << t;
  EXPECT_EQ(detector.last_failure, RestCondition::coordination);
  // Z still, 30 of 100 contacts replaced by others: a change of 60/130 > 0.2 restarts the window.
  EXPECT_FALSE(detector.update(sample(31.0, 0.5, 5.0)));
  RestSample moved = sample(32.0, 0.5, 5.0, 70);
  for (std::uint32_t k = 0; k < 30; ++k) moved.pairs.emplace_back(1, 2 + k);
  std::sort(moved.pairs.begin(), moved.pairs.end());
  EXPECT_FALSE(detector.update(moved));
  EXPECT_EQ(detector.last_failure, RestCondition::contacts);
  EXPECT_NEAR(detector.last_contact_change, 60.0 / 130.0, 1e-15);
  // With 40 grains one contact moves Z by 0.05 and the bound is two contacts' worth, 0.1: a change
  // of 0.075 (1.5 contacts) does not close the window, 0.125 does.
  RestDetector small;
  small.criterion = detector.criterion;
  small.armed = true;
  RestSample few = sample(0.0, 0.5, 3.0);
  few.grains = 40;
  EXPECT_FALSE(small.update(few));
  few.time = 1.0;
  few.coordination = 3.075;
  EXPECT_FALSE(small.update(few));
  EXPECT_EQ(small.window_start, 0.0);
  few.time = 2.0;
  few.coordination = 3.125;
  EXPECT_FALSE(small.update(few));
  EXPECT_EQ(small.window_start, 2.0);
  EXPECT_EQ(small.last_failure, RestCondition::coordination);
  // The new window, with `moved` as reference, holds for the duration: rest at t = 42.
  for (double t = 33.0; t < 42.0; t += 1.0) {
    moved.time = t;
    EXPECT_FALSE(detector.update(moved)) << t;
  }
  moved.time = 42.0;
  EXPECT_TRUE(detector.update(moved));
}

TEST(RestSample, QuantileOfSurfaceSpeedsAndGeometricContacts) {
  Model model;
  model.materials.push_back(Material{"rock", 1000.0});
  for (int k = 0; k < 100; ++k) add_sphere(model, 0.5, 0);
  State state;
  state.resize(100);
  // Grain k moves at k mm/s; grain 99 also spins at 10 rad/s (surface speed 5 m/s more).
  for (std::size_t b = 0; b < 100; ++b) state.velocity[b] = Vec3(0.0, 1e-3 * static_cast<double>(b), 0.0);
  state.angular_velocity[99] = Vec3(10.0, 0.0, 0.0);
  ContactList contacts(3);
  contacts[0].id = ContactId{0, 1, 0, 0};
  contacts[0].gap = -1e-4;  // touching
  contacts[1].id = ContactId{1, 2, 0, 0};
  contacts[1].gap = 0.004;  // within 1% of the radius 0.5
  contacts[2].id = ContactId{2, 3, 0, 0};
  contacts[2].gap = 0.006;  // beyond it
  const RestSample p99 = rest_sample(model, state, contacts, 0.99);
  EXPECT_DOUBLE_EQ(p99.speed, 98e-3);  // the 99th of 100 by nearest rank
  EXPECT_DOUBLE_EQ(rest_sample(model, state, contacts, 1.0).speed, 99e-3 + 10.0 * 0.5);
  EXPECT_DOUBLE_EQ(rest_sample(model, state, contacts, 0.5).speed, 49e-3);
  ASSERT_EQ(p99.pairs.size(), 2u);
  EXPECT_DOUBLE_EQ(p99.coordination, 2.0 * 2.0 / 100.0);
  EXPECT_EQ(contact_change_fraction(p99.pairs, p99.pairs), 0.0);
  EXPECT_EQ(p99.grains, 100u);
  EXPECT_TRUE(rest_starts_armed(model, state));
  State still;
  still.resize(100);
  EXPECT_FALSE(rest_starts_armed(model, still));
}

// An exact exponential decay s = 1000 exp(-t/50) from t = 0: the rest speed 1 is crossed at
// t* = 50 ln 1000 = 345.4; with a duration 20, rest at 365.4. The estimate made at t = 150 must
// say so (to 1 s: the history is an exact exponential).
TEST(RestDetector, EstimatesTheRestTimeFromAnExponentialDecay) {
  RestDetector detector;
  detector.criterion = RestCriterion{1.0, 0.99, 0.05, 0.2, 20.0};
  detector.decay_window = 50.0;
  EXPECT_FALSE(detector.estimated_rest_time().has_value());
  for (double t = 0.0; t <= 150.0; t += 0.5) detector.update(sample(t, 1000.0 * std::exp(-t / 50.0)));
  ASSERT_TRUE(detector.estimated_rest_time().has_value());
  EXPECT_NEAR(*detector.estimated_rest_time(), 50.0 * std::log(1000.0) + 20.0, 1.0);
  // A rising speed has no estimate.
  RestDetector rising;
  rising.criterion = RestCriterion{1.0, 0.99, 0.05, 0.2, 20.0};
  for (double t = 0.0; t <= 10.0; t += 0.5) rising.update(sample(t, 2.0 + t));
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
