// Integrator pieces without contacts: exponential map, gyroscopic free rotation.
#include <gtest/gtest.h>

#include <numbers>

#include "core/integrator.hpp"

namespace rubble {
namespace {

TEST(QuaternionExp, ConstantSpinTurnsByOmegaT) {
  const Vec3 omega(0.3, -1.2, 0.5);
  Quat q = Quat::Identity();
  const double h = 1e-3;
  for (int k = 0; k < 1000; ++k) q = (quaternion_exp(h * omega) * q).normalized();
  const Eigen::AngleAxisd expected(omega.norm() * 1.0, omega.normalized());
  EXPECT_LT(q.angularDistance(Quat(expected)), 1e-12);
  EXPECT_NEAR(q.norm(), 1.0, 1e-15);
}

TEST(QuaternionExp, TinyRotationsUseTheSeries) {
  const Vec3 w(1e-9, 2e-9, -1e-9);
  const Quat q = quaternion_exp(w);
  EXPECT_NEAR(q.w(), std::cos(0.5 * w.norm()), 1e-18);
  EXPECT_NEAR(q.x(), 0.5e-9, 1e-22);
}

TEST(FrameFromNormal, IsRightHandedAndOrthonormal) {
  for (const Vec3& n : {Vec3(0, 0, 1), Vec3(0, 0, -1), Vec3(1, 2, 3).normalized(), Vec3(-1, 0, -1e-9).normalized()}) {
    const Mat3 f = frame_from_normal(n);
    EXPECT_LT((f.transpose() * f - Mat3::Identity()).norm(), 1e-14);
    EXPECT_NEAR(f.determinant(), 1.0, 1e-14);
    EXPECT_LT((f.col(0) - n).norm(), 1e-15);
  }
}

// A box spinning about a principal axis keeps spinning about it (the gyroscopic term vanishes),
// and spinning about a tilted axis the explicit gyroscopic term conserves the angular momentum
// to first order: checked loosely here; the stability suite checks the Dzhanibekov flip.
TEST(FreeRotation, PrincipalAxisSpinIsSteadyAndMomentumNearlyConserved) {
  Model m;
  m.materials.push_back({"rock", 1000});
  ConvexPolyhedron shape;  // only the inertia matters here
  add_polyhedron(m, shape, 1.0, Vec3(1.0, 2.0, 3.0), 0);
  State s;
  s.resize(1);
  s.angular_velocity[0] = Vec3(0, 0, 4.0);
  BodyVelocities v;
  IntegratorOptions options{1e-3, 0.5};
  for (int k = 0; k < 1000; ++k) {
    compute_free_velocity(m, s, std::vector<Vec3>{Vec3::Zero()}, {}, options.time_step, v);
    update_positions(m, options, v, s);
  }
  EXPECT_LT((s.angular_velocity[0] - Vec3(0, 0, 4.0)).norm(), 1e-12);

  s.angular_velocity[0] = Vec3(0.01, 0.0, 4.0);
  s.orientation[0] = Quat::Identity();
  auto angular_momentum = [&] {
    const Mat3 R = s.orientation[0].toRotationMatrix();
    return Vec3(R * m.principal_inertia[0].asDiagonal() * R.transpose() * s.angular_velocity[0]);
  };
  const Vec3 L0 = angular_momentum();
  for (int k = 0; k < 1000; ++k) {
    compute_free_velocity(m, s, std::vector<Vec3>{Vec3::Zero()}, {}, options.time_step, v);
    update_positions(m, options, v, s);
  }
  EXPECT_LT((angular_momentum() - L0).norm(), 1e-3 * L0.norm());
}

}  // namespace
}  // namespace rubble
