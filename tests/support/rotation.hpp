#pragma once
// Rotations the tests build scenes with.
#include <cmath>

#include "core/math.hpp"

namespace rubble::testing {

/// The shortest rotation that takes the direction of `from` to that of `to`: Eigen's
/// Quaternion::FromTwoVectors to the bit, without the JacobiSVD it instantiates for opposite
/// vectors (about 5 s of compile in every test file that used it). For opposite directions (within
/// 1e-12) it is the half turn about from × y (from × z when `from` is along y): for from = +z
/// the half turn about -x, which is what that SVD returns.
inline Quat rotation_between(const Vec3& from, const Vec3& to) {
  const Vec3 v0 = from.normalized();
  const Vec3 v1 = to.normalized();
  const double c = v1.dot(v0);
  if (c < -1.0 + 1e-12) {
    Vec3 axis = v0.cross(Vec3::UnitY());
    if (axis.squaredNorm() < 1e-12) axis = v0.cross(Vec3::UnitZ());
    axis.normalize();
    return Quat(0.0, axis.x(), axis.y(), axis.z());
  }
  const Vec3 axis = v0.cross(v1);
  const double s = std::sqrt((1.0 + c) * 2.0);
  const double inverse_s = 1.0 / s;
  return Quat(s * 0.5, axis.x() * inverse_s, axis.y() * inverse_s, axis.z() * inverse_s);
}

}  // namespace rubble::testing
