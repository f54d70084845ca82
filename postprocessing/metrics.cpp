#include "postprocessing/metrics.hpp"

namespace rubble {

double kinetic_energy(const Model& model, const State& state) {
  double energy = 0.0;
  for (std::size_t i = 0; i < model.body_count(); ++i) {
    if (model.is_fixed(i)) continue;
    // Rotation in the body frame: w_body = R^T w, E = 1/2 sum_k I_k w_body,k^2.
    const Vec3 w_body = state.orientation[i].conjugate() * state.angular_velocity[i];
    energy += 0.5 * model.mass[i] * state.velocity[i].squaredNorm() +
              0.5 * w_body.dot(model.principal_inertia[i].cwiseProduct(w_body));
  }
  return energy;
}

}  // namespace rubble
