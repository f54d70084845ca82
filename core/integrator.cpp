#include "core/integrator.hpp"

#include "core/parallel.hpp"

namespace rubble {

Vec3 torque_free_rotation(const Vec3& inertia, const Vec3& omega, double time_step) {
  // Conservation of the world angular momentum over the step, with the orientation advanced by
  // exp(h w_mid) (what update_positions does for theta = 0.5): in the body frame at t_n,
  //   w+ = Q I^-1 Q^T I w,   Q = exp(h [w_mid]),   w_mid = (w + w+)/2,
  // solved by fixed-point iteration (a contraction for h |w| << 1). The gyroscopic term is thus
  // implicit and |L| is exact; the kinetic energy error stays O((h |w|)^2) without drift.
  const Vec3 momentum = inertia.cwiseProduct(omega);
  Vec3 next = omega;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const Mat3 q = quaternion_exp(0.5 * time_step * (omega + next)).toRotationMatrix();
    const Vec3 updated = q * (q.transpose() * momentum).cwiseQuotient(inertia);
    const double change = (updated - next).norm();
    next = updated;
    if (change <= 1e-15 * (omega.norm() + 1e-300)) break;
  }
  return next;
}

void compute_free_velocity(const Model& model, const State& state, std::span<const Vec3> force,
                           std::span<const Vec3> torque, double time_step, BodyVelocities& free_velocity) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(model.body_count());
  free_velocity.linear.resize(static_cast<std::size_t>(n));
  free_velocity.angular.resize(static_cast<std::size_t>(n));
#pragma omp parallel for schedule(static) if (n >= min_parallel_items)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto b = static_cast<std::size_t>(i);
    if (model.is_fixed(b)) {
      free_velocity.linear[b] = Vec3::Zero();
      free_velocity.angular[b] = Vec3::Zero();
      continue;
    }
    free_velocity.linear[b] = state.velocity[b] + time_step * model.inverse_mass[b] * force[b];
    // Rotation in the body frame at t_n, where the inertia is diagonal.
    const Mat3 rotation = state.orientation[b].toRotationMatrix();
    const Vec3 omega_body = rotation.transpose() * state.angular_velocity[b];
    Vec3 omega_free_body = model.shape_kind[b] == ShapeKind::sphere
                               ? omega_body
                               : torque_free_rotation(model.principal_inertia[b], omega_body, time_step);
    if (!torque.empty()) {
      omega_free_body += time_step * model.inverse_inertia[b].cwiseProduct(rotation.transpose() * torque[b]);
    }
    free_velocity.angular[b] = rotation * omega_free_body;
  }
}

void update_positions(const Model& model, const IntegratorOptions& options, const BodyVelocities& velocity,
                      State& state) {
  const double h = options.time_step;
  const double theta = options.theta;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(model.body_count());
#pragma omp parallel for schedule(static) if (n >= min_parallel_items)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto b = static_cast<std::size_t>(i);
    if (model.is_fixed(b)) continue;
    const Vec3 v_theta = (1.0 - theta) * state.velocity[b] + theta * velocity.linear[b];
    const Vec3 w_theta = (1.0 - theta) * state.angular_velocity[b] + theta * velocity.angular[b];
    state.position[b] += h * v_theta;
    // Exponential map keeps the orientation on the unit sphere; renormalise against round-off.
    state.orientation[b] = (quaternion_exp(h * w_theta) * state.orientation[b]).normalized();
    state.velocity[b] = velocity.linear[b];
    state.angular_velocity[b] = velocity.angular[b];
  }
  state.time += h;
  state.step += 1;
}

}  // namespace rubble
