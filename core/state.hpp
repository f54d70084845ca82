#pragma once
// The state: the bodies' positions, orientations and velocities at one instant, and the time and
// step. A plain struct of arrays, indexed by body id like the model (core/model.hpp, which does
// not change during a run).
//
// The state alone does not restart a run bit for bit. A restart also needs what the last step
// hands to the next (simulation/step_carry.hpp, StepCarry: last step's contacts with their
// impulses for the warm start, the detection memory of polyhedron pairs, the held self-gravity
// field) and the run loop's bookkeeping (simulation/checkpoint.hpp: RunProgress, RestWatch). A
// checkpoint saves all of them with the scene text the model is rebuilt from. A run started from
// a state alone (rubble run SCENE --from RUN_DIR:snapshot=K, a snapshot of the run file) starts
// cold: no warm start, so it follows a slightly different path.
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
