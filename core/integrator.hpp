#pragma once
// The Moreau-Jean time step in Moreau's midpoint form (Moreau 1988, "Unilateral contact and dry
// friction in finite freedom dynamics"; Jean 1999), split into the pieces the step calls. Over a
// step of length h with parameter theta in [1/2, 1]:
//   drift to the midpoint   q_m     = q_n + (1 - theta) h v_n            (drift_to_midpoint)
//   free velocity           v_free  = v_n + h M^-1 f(q_m)                (+ gyroscopic term)
//   contacts at q_m         v_{n+1} = v_free + M^-1 H(q_m) r             (the solver, contact by contact)
//   drift to the end        q_{n+1} = q_m + theta h v_{n+1}              (finish_step)
// The positions follow the theta-method x_{n+1} = x_n + h((1 - theta) v_n + theta v_{n+1}); the
// forces and the contacts are taken at q_m, not at q_n. Without contacts this is a drift-kick-drift
// composition of exact flows, hence symplectic for every theta; for theta = 1/2 it is the
// Stoermer-Verlet scheme (second order, energy error bounded without drift: Hairer, Lubich & Wanner
// 2006, Geometric Numerical Integration, ch. VI and IX). Evaluating f at q_n instead (the earlier
// scheme) is neither symplectic nor second order for a position-dependent force: a Kepler orbit
// gained 30 % energy in 10 orbits. theta > 1/2 damps only through the contacts (the impact and
// the gap are weighted by theta), never the smooth motion.
#include <span>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Settings of the time integrator.
struct IntegratorOptions {
  double time_step = 1e-4;  ///< h, s
  double theta = 0.5;       ///< theta in [0.5, 1]: where in the step the configuration q_m is taken
};

/// Body velocities being worked on within a step (the solver updates them in place).
struct BodyVelocities {
  std::vector<Vec3> linear;   ///< m/s, world frame
  std::vector<Vec3> angular;  ///< rad/s, world frame
};

/// Torque-free rotation over one step of a body with principal inertia `inertia` (kg m^2).
/// `omega` is the angular velocity at t_n expressed in the body frame at the midpoint orientation
/// R_m = exp((1 - theta) h w_n) R_n. Returns w_{n+1} in that same frame, such that the world
/// angular momentum is conserved exactly when the orientation is advanced by
/// R_{n+1} = exp(theta h w_{n+1}) R_m (what finish_step does): the gyroscopic term of Euler's
/// equations taken implicitly. For theta = 1/2 the kinetic energy error is bounded, O((h|w|)^2);
/// for theta = 1 the energy decays (backward Euler in the rotation), it never grows.
Vec3 torque_free_rotation(const Vec3& inertia, const Vec3& omega, double time_step, double theta);

/// Stage "drift_to_midpoint": moves every free or driven body (Model::is_driven) to
/// q_m = q_n + (1 - theta) h v_n (position and orientation); velocities, time and step are left as
/// they are (still those of t_n).
void drift_to_midpoint(const Model& model, const IntegratorOptions& options, State& state);

/// Free velocity: the velocity at the end of the step if no contact acted. `state` holds the
/// midpoint configuration q_m and the velocities v_n; `force` and `torque` (world frame, N and N m)
/// are the external actions at q_m, one per body; `torque` may be empty. Non-spherical bodies turn
/// by `torque_free_rotation` (implicit gyroscopic term), then the torque impulse is added. Bodies of
/// infinite mass get zero, or a driven body its prescribed velocity at t_{n+1}: with theta = 1/2 its
/// position then advances by h (v(t_n) + v(t_{n+1})) / 2, the trapezoidal rule, exact for a
/// velocity linear over the step.
void compute_free_velocity(const Model& model, const State& state, std::span<const Vec3> force,
                           std::span<const Vec3> torque, const IntegratorOptions& options,
                           BodyVelocities& free_velocity);

/// Stage "finish_step": q_{n+1} = q_m + theta h v_{n+1} + h w, where `velocity` holds v_{n+1} and
/// `displacement_velocity` (may be empty) a pseudo-velocity w that moves positions only (the
/// overlap recovery, nlgs_solver/overlap_recovery.hpp); stores v_{n+1} in the state and advances
/// time and step.
void finish_step(const Model& model, const IntegratorOptions& options, const BodyVelocities& velocity,
                 const BodyVelocities& displacement_velocity, State& state);

}  // namespace rubble
