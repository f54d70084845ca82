// Rolling and twisting resistance (ContactLaw::rolling_friction, twisting_friction) of sphere
// contacts against closed forms: a solid sphere (I = 2/5 m r^2) on a plane feels a resisting
// angular impulse of at most mu_r r N h (rolling) and mu_t r N h (twisting) per step. And the
// angular impulses' warm start and checkpoint: a held sphere resumes bit for bit.
#include <gtest/gtest.h>

#include <cmath>

#include "simulation/checkpoint.hpp"
#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;
constexpr double g = 9.81;
constexpr double radius = 0.05;  // m

/// A sphere of radius `radius` touching a plane through the origin with normal `normal`, h = 1 ms,
/// the contact law mu = 0.8 (enough to roll without slipping) with rolling and twisting friction
/// `mu_r`, `mu_t`. The sphere is body `ball` of the returned scene, at rest.
struct SphereOnAPlane {
  TestScene scene{2500.0, 0.8, 0.0};
  std::size_t ball = 0;
  Vec3 start;  ///< the sphere's initial position
};
SphereOnAPlane sphere_on_a_plane(const Vec3& normal, double mu_r, double mu_t) {
  SphereOnAPlane s;
  s.scene.uniform_gravity(g);
  s.scene.options.integrator.time_step = 1e-3;
  ContactLaw law{0.8, 0.0};
  law.rolling_friction = mu_r;
  law.twisting_friction = mu_t;
  s.scene.model.contact_laws.reset(1, law);
  s.scene.plane(Vec3::Zero(), normal);
  s.start = radius * normal;
  s.ball = static_cast<std::size_t>(s.scene.sphere(radius, s.start));
  return s;
}

/// A sphere at rest on a plane through the origin tilted by `alpha` about x, Coulomb mu = 0.8
/// (enough to roll without slipping below tan(alpha) = 2.8 mu / 1 for a rolling sphere) and
/// rolling friction `mu_r`. Returns the downhill velocity after `seconds` and the displacement.
struct Roll {
  double velocity = 0.0;      ///< m/s, downhill
  double displacement = 0.0;  ///< m
  double spin = 0.0;          ///< rad/s, about the axis of rolling
};
Roll roll_down(double alpha, double mu_r, double seconds) {
  const Quat tilt(Eigen::AngleAxisd(alpha, Vec3::UnitX()));
  const Vec3 normal = tilt * Vec3::UnitZ();
  SphereOnAPlane s = sphere_on_a_plane(normal, mu_r, 0.0);
  s.scene.run(seconds);
  const State& state = s.scene.state;
  const Vec3 downhill = -(tilt * Vec3::UnitY());
  return {state.velocity[s.ball].dot(downhill), (state.position[s.ball] - s.start).norm(),
          state.angular_velocity[s.ball].dot(normal.cross(downhill))};
}

// Reference: at rest, friction f = m g sin(alpha) holds the sphere, and its torque f r must be
// balanced by the rolling resistance, at most mu_r r m g cos(alpha): the sphere stays below
// tan(alpha) = mu_r. Above, rolling without slipping with the resisting torque mu_r r N:
// a = g (sin(alpha) - mu_r cos(alpha)) / (1 + I / (m r^2)) = 5/7 g (sin(alpha) - mu_r cos(alpha)).
// Pass (mu_r = 0.1): at tan(alpha) = 0.99 mu_r the sphere moves < 1e-9 m in 1 s; at 1.01 mu_r it
// rolls (> 1e-6 m); at tan(alpha) = 3 mu_r the velocity after 0.5 s is 5/7 g (...) t within 1 %
// and the spin is v / r within 1e-6 (rolling, not slipping).
TEST(RotationResistance, SphereOnAnInclineStopsBelowTanAlphaEqualMuR) {
  const double mu_r = 0.1;
  const Roll below = roll_down(std::atan(0.99 * mu_r), mu_r, 1.0);
  const Roll above = roll_down(std::atan(1.01 * mu_r), mu_r, 1.0);
  const double alpha = std::atan(3 * mu_r);
  const Roll rolling = roll_down(alpha, mu_r, 0.5);
  const double expected = 5.0 / 7.0 * g * (std::sin(alpha) - mu_r * std::cos(alpha)) * 0.5;
  std::cout << "rolling resistance: 0.99 mu_r moved " << below.displacement << " m, 1.01 mu_r " << above.displacement
            << " m; at 3 mu_r v = " << rolling.velocity << " m/s (closed form " << expected
            << "), spin r / v = " << rolling.spin * radius / rolling.velocity << "\n";
  EXPECT_LT(below.displacement, 1e-9);
  EXPECT_GT(above.displacement, 1e-6);
  EXPECT_NEAR(rolling.velocity, expected, 0.01 * expected);
  EXPECT_NEAR(rolling.spin * radius, rolling.velocity, 1e-6 * rolling.velocity);
}

// Reference: a sphere rolling on a level plane at v0 is slowed by the resisting torque
// mu_r r m g: a = -5/7 mu_r g, so it stops at t* = 7 v0 / (5 mu_r g) after 7 v0^2 / (10 mu_r g).
// Pass (v0 = 1 m/s, mu_r = 0.05, t* = 2.854 s): v(1 s) = v0 - 5/7 mu_r g within 1 %; after 4 s it
// is at rest (< 1e-9 m/s) and has travelled the closed-form distance within 1 %.
TEST(RotationResistance, RollingSphereStopsAtTheClosedFormDistance) {
  const double mu_r = 0.05, v0 = 1.0;
  auto run = [&](double seconds, double& distance) {
    SphereOnAPlane s = sphere_on_a_plane(Vec3::UnitZ(), mu_r, 0.0);
    State& state = s.scene.state;
    state.velocity[s.ball] = Vec3(v0, 0, 0);
    state.angular_velocity[s.ball] = Vec3(0, v0 / radius, 0);  // rolling: v = omega x (-r e_z)
    s.scene.run(seconds);
    distance = state.position[s.ball].x();
    return state.velocity[s.ball].x();
  };
  double d1 = 0.0, d4 = 0.0;
  const double v1 = run(1.0, d1);
  const double v4 = run(4.0, d4);
  const double expected_v1 = v0 - 5.0 / 7.0 * mu_r * g;
  const double expected_distance = 7.0 * v0 * v0 / (10.0 * mu_r * g);
  std::cout << "rolling to a stop: v(1 s) " << v1 << " m/s (closed form " << expected_v1 << "), v(4 s) " << v4
            << " m/s, distance " << d4 << " m (closed form " << expected_distance << ")\n";
  EXPECT_NEAR(v1, expected_v1, 0.01 * expected_v1);
  EXPECT_LT(std::abs(v4), 1e-9);
  EXPECT_NEAR(d4, expected_distance, 0.01 * expected_distance);
}

// Reference: a sphere spinning at omega0 about the normal of a level plane is slowed by the
// twisting torque mu_t r m g: I d(omega)/dt = -mu_t r m g, omega(t) = omega0 - 5 mu_t g t / (2 r),
// at rest after t* = 2 r omega0 / (5 mu_t g). Pass (omega0 = 20 rad/s, mu_t = 0.1, t* = 0.408 s):
// omega(0.2 s) within 1 % of the closed form; at rest after 0.5 s (< 1e-9 rad/s); the centre
// does not move (< 1e-9 m).
TEST(RotationResistance, SpinningSphereStopsAtTheTwistingRate) {
  const double mu_t = 0.1, omega0 = 20.0;
  auto run = [&](double seconds, double& moved) {
    SphereOnAPlane s = sphere_on_a_plane(Vec3::UnitZ(), 0.0, mu_t);
    State& state = s.scene.state;
    state.angular_velocity[s.ball] = Vec3(0, 0, omega0);
    s.scene.run(seconds);
    moved = (state.position[s.ball] - s.start).norm();
    return state.angular_velocity[s.ball].z();
  };
  double moved = 0.0, moved_end = 0.0;
  const double at_02 = run(0.2, moved);
  const double at_05 = run(0.5, moved_end);
  const double expected = omega0 - 5.0 * mu_t * g * 0.2 / (2.0 * radius);
  std::cout << "twisting: omega(0.2 s) " << at_02 << " rad/s (closed form " << expected << "), omega(0.5 s) " << at_05
            << " rad/s, centre moved " << moved_end << " m\n";
  EXPECT_NEAR(at_02, expected, 0.01 * expected);
  EXPECT_LT(std::abs(at_05), 1e-9);
  EXPECT_LT(moved_end, 1e-9);
}

/// The sphere of sphere_on_a_plane on a plane tilted by `alpha` about x, with rolling friction
/// `mu_r`: held at rest when tan(alpha) < mu_r (test above).
SphereOnAPlane sphere_on_an_incline(double alpha, double mu_r) {
  const Quat tilt(Eigen::AngleAxisd(alpha, Vec3::UnitX()));
  return sphere_on_a_plane(tilt * Vec3::UnitZ(), mu_r, 0.0);
}

/// `checkpoint.carry` and `state` through the checkpoint's bytes and back (what a resume loads).
Checkpoint through_checkpoint_bytes(const State& state, const StepCarry& carry) {
  Checkpoint checkpoint;
  checkpoint.scene_text = "a sphere held on an incline";
  checkpoint.state = state;
  checkpoint.carry = carry;
  checkpoint.progress.end_step = state.step;
  return deserialize_checkpoint(serialize_checkpoint(checkpoint), "memory");
}

// Reference: an uninterrupted run. A sphere held on an incline by rolling resistance (tan(alpha)
// = 0.5 mu_r, mu_r = 0.1) carries a rolling impulse step after step: the torque of the friction
// that holds it, m g sin(alpha) r, times h (within 1e-6; half its bound). Stepped 300 steps,
// checkpointed (serialised to bytes and read back), resumed in a fresh workspace for 300 more:
// the state must be bit-identical (state hash) to 600 uninterrupted steps, and the sphere still
// held (< 1e-9 m). That the check can fail: the same resume with the loaded angular impulses set
// to zero (what a checkpoint without them gives) must differ.
TEST(RotationResistance, HeldSphereResumesBitForBitFromACheckpoint) {
  const double mu_r = 0.1, alpha = std::atan(0.5 * mu_r);
  SphereOnAPlane whole = sphere_on_an_incline(alpha, mu_r);
  whole.scene.steps(600);

  SphereOnAPlane first = sphere_on_an_incline(alpha, mu_r);
  first.scene.steps(300);
  const Checkpoint saved = through_checkpoint_bytes(first.scene.state, first.scene.workspace.carry);
  ASSERT_EQ(saved.carry.contacts.size(), 1u);
  const Contact& held = saved.carry.contacts[0];
  const double mass = 2500.0 * 4.0 / 3.0 * M_PI * std::pow(radius, 3);
  // The rolling impulse that holds the sphere: the torque of friction, m g sin(alpha) r, over h.
  const double holding = mass * g * std::sin(alpha) * radius * 1e-3;
  EXPECT_NEAR(held.angular_impulse.tail<2>().norm(), holding, 1e-6 * holding);
  EXPECT_EQ(held.angular_impulse, first.scene.workspace.carry.contacts[0].angular_impulse);

  auto resume = [&](bool keep_angular_impulses) {
    SphereOnAPlane resumed = sphere_on_an_incline(alpha, mu_r);
    resumed.scene.state = saved.state;
    resumed.scene.workspace.carry = saved.carry;
    if (!keep_angular_impulses) resumed.scene.workspace.carry.contacts[0].angular_impulse = Vec3::Zero();
    resumed.scene.steps(300);
    return state_hash(resumed.scene.state);
  };
  const std::uint64_t uninterrupted = state_hash(whole.scene.state);
  EXPECT_EQ(resume(true), uninterrupted);
  EXPECT_NE(resume(false), uninterrupted);
  EXPECT_LT((whole.scene.state.position[whole.ball] - whole.start).norm(), 1e-9);  // still held
}

/// Mean sweeps a step of a sphere held on an incline (tan(alpha) = 0.5 mu_r) over steps 101-300:
/// warm start of forces and angular impulses (`warm`), of the forces only (the angular impulses
/// set to zero before each step, as before they were carried), or none.
enum class WarmStart { all, forces_only, none };
double mean_sweeps_of_a_held_sphere(WarmStart warm) {
  const double mu_r = 0.1;
  SphereOnAPlane s = sphere_on_an_incline(std::atan(0.5 * mu_r), mu_r);
  s.scene.options.solver.warm_start = warm != WarmStart::none;
  double sweeps = 0.0;
  for (int k = 0; k < 300; ++k) {
    if (warm == WarmStart::forces_only) {
      for (Contact& c : s.scene.workspace.carry.contacts) c.angular_impulse = Vec3::Zero();
    }
    const StepReport& report = s.scene.advance();
    if (k >= 100) sweeps += report.solver.iterations;
  }
  return sweeps / 200.0;
}

// Reference: the cold solve. On a held contact last step's impulses are this step's solution up to
// the tolerance (1e-10 here), so a warm-started step needs fewer sweeps. Measured (2026-11-24):
// 1 sweep a step with the angular impulses warm-started, 61 with the forces' warm start alone (as
// before the angular impulses were carried), 61 cold: the force and the rolling block of one
// contact converge one from the other sweep after sweep, and only the pair warm-starts that.
TEST(RotationResistance, WarmStartOfTheAngularImpulsesSavesSweepsOnAHeldContact) {
  const double all = mean_sweeps_of_a_held_sphere(WarmStart::all);
  const double forces_only = mean_sweeps_of_a_held_sphere(WarmStart::forces_only);
  const double none = mean_sweeps_of_a_held_sphere(WarmStart::none);
  std::cout << "held sphere, mean sweeps a step: warm start " << all << ", forces only " << forces_only << ", cold "
            << none << "\n";
  EXPECT_LT(all, forces_only);
  EXPECT_LT(all, none);
}

}  // namespace
}  // namespace rubble
