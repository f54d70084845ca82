#include "simulation/initial_conditions.hpp"

namespace rubble {

std::vector<std::size_t> selected_grains(const Model& model, const State& state, const InitialCondition& condition) {
  std::vector<std::size_t> grains;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_grain(b) || model.is_fixed(b)) continue;
    if (condition.material >= 0 && model.material[b] != condition.material) continue;
    if (condition.region_min && condition.region_max) {
      const Vec3& x = state.position[b];
      if ((x.array() < condition.region_min->array()).any() || (x.array() > condition.region_max->array()).any()) {
        continue;
      }
    }
    grains.push_back(b);
  }
  return grains;
}

std::optional<std::size_t> apply_initial_conditions(const Model& model, const std::vector<InitialCondition>& conditions,
                                                    State& state) {
  for (std::size_t k = 0; k < conditions.size(); ++k) {
    const InitialCondition& condition = conditions[k];
    const std::vector<std::size_t> grains = selected_grains(model, state, condition);
    if (grains.empty()) return k;
    Vec3 centre = Vec3::Zero();
    if (condition.centre) {
      centre = *condition.centre;
    } else {
      double mass = 0.0;
      for (const std::size_t b : grains) {
        centre += model.mass[b] * state.position[b];
        mass += model.mass[b];
      }
      centre /= mass;
    }
    for (const std::size_t b : grains) {
      state.velocity[b] += condition.velocity + condition.angular_velocity.cross(state.position[b] - centre);
      state.angular_velocity[b] += condition.angular_velocity;
    }
  }
  return std::nullopt;
}

}  // namespace rubble
