// Tangential restitution (ContactLaw::tangential_restitution, nlgs_solver/README.md): Coulomb's law
// on the weighted tangential velocity u_t+ + e_t u_t- (Moreau 1988). Closed forms for a solid
// sphere (I = 2/5 m r^2) striking a plane obliquely at (V, 0, -V) without spin, no gravity:
//  - sticking impact (mu large): the contact point's sliding velocity reverses times e_t. A
//    tangential impulse P changes it by (1 + 5/2) P / m, so P = -(2/7)(1 + e_t) m V and the centre
//    leaves at v_x = V (5 - 2 e_t) / 7 (5/7 V, rolling, at e_t = 0; 3/7 V at e_t = 1);
//  - sliding impact (mu small): the friction bound mu (1 + e_n) m V acts whatever e_t, so
//    v_x = V (1 - mu (1 + e_n)).
// The normal part is Newton's e_n either way: v_z = e_n V.
#include <gtest/gtest.h>

#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

struct Bounce {
  Vec3 velocity;        ///< of the centre after the impact, m/s
  double contact_slip;  ///< tangential velocity of the contact point after the impact, m/s
};

Bounce oblique_bounce(double friction, double normal_restitution, double tangential_restitution) {
  TestScene s(2500.0, friction, normal_restitution);
  ContactLaw law{friction, normal_restitution};
  law.tangential_restitution = tangential_restitution;
  s.model.contact_laws.reset(1, law);
  const double radius = 0.05, speed = 1.0;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  const int ball = s.sphere(radius, Vec3(0, 0, radius + 2.5e-4), Vec3(speed, 0, -speed));
  s.run(0.01);  // the impact at 0.25 ms, then free flight
  const auto b = static_cast<std::size_t>(ball);
  const Vec3 v = s.state.velocity[b], w = s.state.angular_velocity[b];
  return {v, v.x() + w.cross(Vec3(0, 0, -radius)).x()};
}

TEST(TangentialRestitution, StickingImpactReversesTheContactPointsSlipTimesEt) {
  for (const double et : {0.0, 0.5, 1.0}) {
    const Bounce bounce = oblique_bounce(10.0, 0.5, et);
    EXPECT_NEAR(bounce.velocity.x(), (5.0 - 2.0 * et) / 7.0, 1e-6) << "e_t = " << et;
    EXPECT_NEAR(bounce.contact_slip, -et, 1e-6) << "e_t = " << et;
    EXPECT_NEAR(bounce.velocity.z(), 0.5, 1e-6) << "e_t = " << et;
  }
}

TEST(TangentialRestitution, SlidingImpactIsBoundByFrictionWhateverEt) {
  for (const double et : {0.0, 0.5}) {
    const Bounce bounce = oblique_bounce(0.1, 0.5, et);
    EXPECT_NEAR(bounce.velocity.x(), 1.0 - 0.1 * 1.5, 1e-6) << "e_t = " << et;
    EXPECT_NEAR(bounce.velocity.z(), 0.5, 1e-6) << "e_t = " << et;
  }
}

// A persistent sliding contact is not changed by e_t: a sphere launched at v0 = 1 m/s without spin
// on a plane (mu = 0.2, g = 9.81) slides with its centre decelerating at mu g until it rolls at
// t = 2 v0 / (7 mu g) = 0.146 s; then it rolls at 5/7 v0 (the angular momentum about the contact
// point is conserved), e_t or not: the slip reversed times e_t at the sticking step decays by e_t a
// step.
TEST(TangentialRestitution, SlidingThenRollingSphereIsUnchangedByEt) {
  for (const double et : {0.0, 0.5}) {
    TestScene s;
    ContactLaw law{0.2, 0.0};
    law.tangential_restitution = et;
    s.model.contact_laws.reset(1, law);
    s.uniform_gravity(9.81);
    s.plane(Vec3::Zero(), Vec3::UnitZ());
    const int ball = s.sphere(0.05, Vec3(0, 0, 0.05), Vec3(1.0, 0, 0));
    const auto b = static_cast<std::size_t>(ball);
    s.run(0.1);
    EXPECT_NEAR(s.state.velocity[b].x(), 1.0 - 0.2 * 9.81 * 0.1, 1e-6) << "e_t = " << et;
    s.run(0.3);
    EXPECT_NEAR(s.state.velocity[b].x(), 5.0 / 7.0, 1e-6) << "e_t = " << et;
    EXPECT_NEAR(s.state.velocity[b].x() - 0.05 * s.state.angular_velocity[b].y(), 0.0, 1e-6) << "e_t = " << et;
  }
}

}  // namespace
}  // namespace rubble
