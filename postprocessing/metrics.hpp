#pragma once
// Metrics of a granular aggregate at one instant (seed 001 section 3): energies and momenta,
// coordination number with and without rattlers, aggregate diameter, packing fraction, contact
// statistics. Definitions are in docs/postprocessing.md; every function takes the immutable
// Model and one State (plus the contacts where needed), so it runs during a run or on a run file.
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Total kinetic energy of the moving bodies, J: sum over bodies of
/// 1/2 m |v|^2 + 1/2 w . (R I R^T) w (translation + rotation; w and v in the world frame,
/// I the principal inertia in the body frame, R the body's rotation). Walls contribute nothing.
double kinetic_energy(const Model& model, const State& state);

}  // namespace rubble
