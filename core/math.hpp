#pragma once
// Small fixed-size linear algebra used everywhere: Eigen's 3-vectors, 3x3 matrices and quaternions.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rubble {

using Vec2 = Eigen::Vector2d;     ///< a 2-vector (the tangential components of a contact-frame vector)
using Vec3 = Eigen::Vector3d;     ///< a 3-vector (position m, velocity m/s, impulse N·s, ...)
using Mat3 = Eigen::Matrix3d;     ///< a 3x3 matrix (inertia, rotation, Delassus block)
using Quat = Eigen::Quaterniond;  ///< a unit quaternion: body frame -> world frame

/// Skew matrix [a]x such that [a]x b = a x b.
inline Mat3 skew(const Vec3& a) {
  Mat3 m;
  m << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
  return m;
}

/// Exponential map of a rotation vector (axis * angle, rad) to a unit quaternion.
/// Uses the series for sin(x)/x near zero so tiny rotations stay exact to round-off.
inline Quat quaternion_exp(const Vec3& rotation_vector) {
  const double angle = rotation_vector.norm();
  const double half = 0.5 * angle;
  // sin(half)/angle, with its Taylor series below 1e-4 rad (error < 1e-17).
  const double k = angle < 1e-4 ? 0.5 - angle * angle / 48.0 : std::sin(half) / angle;
  return Quat(std::cos(half), k * rotation_vector.x(), k * rotation_vector.y(), k * rotation_vector.z());
}

/// Builds a right-handed orthonormal frame whose first column is the unit vector n
/// (Duff et al. 2017, "Building an orthonormal basis, revisited"): continuous in n except
/// on the plane n.z = 0 sign flip, and deterministic.
inline Mat3 frame_from_normal(const Vec3& n) {
  const double sign = std::copysign(1.0, n.z());
  const double a = -1.0 / (sign + n.z());
  const double b = n.x() * n.y() * a;
  Mat3 frame;
  frame.col(0) = n;
  frame.col(1) = Vec3(1.0 + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
  frame.col(2) = Vec3(b, sign + n.y() * n.y() * a, -n.y());
  return frame;
}

}  // namespace rubble
