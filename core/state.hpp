#pragma once
// The state: everything that changes during a run. A plain struct of arrays, indexed by body id
// like the model; with the model it is all a checkpoint needs.
#include <cstdint>
#include <vector>

#include "core/math.hpp"

namespace rubble {

/// Positions, orientations and velocities of every body at one instant.
struct State {
  double time = 0.0;                   ///< s
  std::int64_t step = 0;               ///< number of steps taken
  std::vector<Vec3> position;          ///< m, centre of mass, world frame
  std::vector<Quat> orientation;       ///< unit quaternion, body frame -> world frame
  std::vector<Vec3> velocity;          ///< m/s, of the centre of mass, world frame
  std::vector<Vec3> angular_velocity;  ///< rad/s, world frame

  /// Resizes to n bodies at rest at the origin with identity orientation.
  void resize(std::size_t n) {
    position.assign(n, Vec3::Zero());
    orientation.assign(n, Quat::Identity());
    velocity.assign(n, Vec3::Zero());
    angular_velocity.assign(n, Vec3::Zero());
  }
  /// Number of bodies.
  std::size_t body_count() const { return position.size(); }
};

}  // namespace rubble
