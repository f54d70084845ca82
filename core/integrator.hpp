#pragma once
// The Moreau-Jean theta-method, split into the pieces the step calls (seed 001 section 2.1;
// Jean 1999). Over a step of length h, with external force f at t + theta h:
//   free velocity      v_free = v_n + h M^-1 f                     (+ gyroscopic torque for rotation)
//   velocity update    v_{n+1} = v_free + M^-1 H r                 (done incrementally by the solver)
//   position update    x_{n+1} = x_n + h ((1 - theta) v_n + theta v_{n+1})
//                      q_{n+1} = exp(h ((1 - theta) w_n + theta w_{n+1})) q_n
// theta = 0.5 is the default (second order for smooth motion, no numerical damping);
// theta = 1 is fully implicit and damps.
#include <span>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Settings of the time integrator.
struct IntegratorOptions {
  double time_step = 1e-4;  ///< h, s
  double theta = 0.5;       ///< theta in [0.5, 1]
};

/// Body velocities being worked on within a step (the solver updates them in place).
struct BodyVelocities {
  std::vector<Vec3> linear;   ///< m/s, world frame
  std::vector<Vec3> angular;  ///< rad/s, world frame
};

/// Torque-free rotation over one step of a body with principal inertia `inertia`: the angular
/// velocity at t_{n+1}, expressed in the body frame at t_n, such that the world angular momentum is
/// conserved exactly when the orientation is advanced by exp(h (w_n + w_{n+1})/2) (theta = 0.5).
/// This is the gyroscopic term of Euler's equations, taken implicitly.
Vec3 torque_free_rotation(const Vec3& inertia, const Vec3& omega, double time_step);

/// Free velocity: the velocity at the end of the step if no contact acted.
/// `force` and `torque` (world frame, N and N m) are the external actions at t + theta h, one per
/// body; `torque` may be empty. For non-spherical inertia the rotation is advanced by
/// `torque_free_rotation` (implicit gyroscopic term), then the torque impulse is added.
void compute_free_velocity(const Model& model, const State& state, std::span<const Vec3> force,
                           std::span<const Vec3> torque, double time_step, BodyVelocities& free_velocity);

/// Position and orientation update of the theta-method, then stores the new velocities in the
/// state and advances time and step. `velocity` holds v_{n+1}; the state still holds v_n.
void update_positions(const Model& model, const IntegratorOptions& options, const BodyVelocities& velocity,
                      State& state);

}  // namespace rubble
