#pragma once
// Initial conditions given to a group of grains after they are placed: a bulk velocity and a
// rigid rotation about their centre of mass (an aggregate set spinning, a cloud thrown at a
// target). Applied to a scene's own state when it is read, and to the state a branch starts from
// (`rubble run SCENE --from RUN`), never on a resume (a resumed run goes on as it was).
#include <optional>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// One `[[initial_conditions]]` entry: grains selected by material and region get
///   v_i += V + omega x (x_i - c),   omega_i += omega,
/// the velocity field of a rigid motion with translation V and rotation omega about c, added to
/// whatever they had (an aggregate at rest becomes a rigid body spinning at omega). Driven bodies
/// and walls are never selected.
struct InitialCondition {
  Vec3 velocity = Vec3::Zero();          ///< V, m/s
  Vec3 angular_velocity = Vec3::Zero();  ///< omega, rad/s, world frame
  std::optional<Vec3> centre;            ///< c, m; unset: the selected grains' centre of mass
  int material = -1;                     ///< only grains of this material (-1: any)
  std::optional<Vec3> region_min;        ///< with region_max: only grains whose centre lies in the box, m
  std::optional<Vec3> region_max;        ///< see region_min
};

/// The grains `condition` selects, in body order.
std::vector<std::size_t> selected_grains(const Model& model, const State& state, const InitialCondition& condition);

/// Adds each condition's rigid motion to the grains it selects, in order. Returns the index of the
/// first condition that selects no grain (nothing is applied from it on), or nothing.
std::optional<std::size_t> apply_initial_conditions(const Model& model, const std::vector<InitialCondition>& conditions,
                                                    State& state);

}  // namespace rubble
