#include "core/integrator.hpp"

#include "core/parallel.hpp"

namespace rubble {

Vec3 torque_free_rotation(const Vec3& inertia, const Vec3& omega, double time_step, double theta) {
  // Everything in the body frame at R_m. The orientation at t_n is R_n = R_m D^T with
  // D = exp(-(1 - theta) h w) (a rotation about w itself, so D^T w = w), hence the world angular
  // momentum in this frame is L = D I w. At the end of the step R_{n+1} = R_m E with
  // E = exp(theta h w+), and L conserved means w+ = E I^-1 E^T L: solved by fixed-point iteration
  // (a contraction for h |w| << 1).
  const Mat3 back = quaternion_exp(-(1.0 - theta) * time_step * omega).toRotationMatrix();
  const Vec3 momentum = back * inertia.cwiseProduct(omega);
  Vec3 next = omega;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const Mat3 e = quaternion_exp(theta * time_step * next).toRotationMatrix();
    const Vec3 updated = e * (e.transpose() * momentum).cwiseQuotient(inertia);
    const double change = (updated - next).norm();
    next = updated;
    if (change <= 1e-15 * (omega.norm() + 1e-300)) break;
  }
  return next;
}

void drift_to_midpoint(const Model& model, const IntegratorOptions& options, State& state) {
  const double drift = (1.0 - options.theta) * options.time_step;
  if (drift == 0.0) return;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(model.body_count());
#pragma omp parallel for schedule(static) if (n >= min_parallel_items)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto b = static_cast<std::size_t>(i);
    if (model.is_fixed(b) && !model.is_driven(b)) continue;  // a still wall
    state.position[b] += drift * state.velocity[b];
    // The exponential map keeps the orientation on the unit sphere; renormalise against round-off.
    state.orientation[b] = (quaternion_exp(drift * state.angular_velocity[b]) * state.orientation[b]).normalized();
  }
}

void compute_free_velocity(const Model& model, const State& state, std::span<const Vec3> force,
                           std::span<const Vec3> torque, const IntegratorOptions& options,
                           BodyVelocities& free_velocity) {
  const double h = options.time_step;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(model.body_count());
  free_velocity.linear.resize(static_cast<std::size_t>(n));
  free_velocity.angular.resize(static_cast<std::size_t>(n));
#pragma omp parallel for schedule(static) if (n >= min_parallel_items)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto b = static_cast<std::size_t>(i);
    if (model.is_fixed(b)) {
      // Infinite mass: no force changes it. A driven body has its prescribed velocity at the end
      // of the step, which the contacts then see (it pushes grains, they do not push it).
      const RigidVelocity v = model.is_driven(b) ? model.driven_velocity(b, state.time + h) : RigidVelocity{};
      free_velocity.linear[b] = v.linear;
      free_velocity.angular[b] = v.angular;
      continue;
    }
    free_velocity.linear[b] = state.velocity[b] + h * model.inverse_mass[b] * force[b];
    // Rotation in the body frame at the midpoint orientation, where the inertia is diagonal.
    const Mat3 rotation = state.orientation[b].toRotationMatrix();
    const Vec3 omega_body = rotation.transpose() * state.angular_velocity[b];
    Vec3 omega_free_body = model.shape_kind[b] == ShapeKind::sphere
                               ? omega_body
                               : torque_free_rotation(model.principal_inertia[b], omega_body, h, options.theta);
    if (!torque.empty()) {
      omega_free_body += h * model.inverse_inertia[b].cwiseProduct(rotation.transpose() * torque[b]);
    }
    free_velocity.angular[b] = rotation * omega_free_body;
  }
}

void finish_step(const Model& model, const IntegratorOptions& options, const BodyVelocities& velocity,
                 const BodyVelocities& displacement_velocity, State& state) {
  const double h = options.time_step;
  const double drift = options.theta * h;
  const bool displaced = !displacement_velocity.linear.empty();
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(model.body_count());
#pragma omp parallel for schedule(static) if (n >= min_parallel_items)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto b = static_cast<std::size_t>(i);
    if (model.is_fixed(b) && !model.is_driven(b)) continue;  // a still wall
    Vec3 translation = drift * velocity.linear[b];
    Vec3 rotation = drift * velocity.angular[b];
    if (displaced) {
      translation += h * displacement_velocity.linear[b];
      rotation += h * displacement_velocity.angular[b];
    }
    state.position[b] += translation;
    state.orientation[b] = (quaternion_exp(rotation) * state.orientation[b]).normalized();
    state.velocity[b] = velocity.linear[b];
    state.angular_velocity[b] = velocity.angular[b];
  }
  state.time += h;
  state.step += 1;
}

}  // namespace rubble
