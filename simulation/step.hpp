#pragma once
// One Moreau-Jean time step, as named stages in order (see step.cpp). This is the only place
// that calls every stage; no stage calls it.
#include <array>
#include <string_view>

#include "contact_detection/detection.hpp"
#include "core/integrator.hpp"
#include "core/model.hpp"
#include "core/state.hpp"
#include "gravity/gravity.hpp"
#include "nlgs_solver/nlgs.hpp"

namespace rubble {

/// Which gravity acts on the grains.
struct GravitySettings {
  enum class Kind { none, uniform, self };
  Kind kind = Kind::none;                          ///< none, a uniform field, or self-gravity
  Vec3 acceleration = Vec3::Zero();                ///< m/s^2, for Kind::uniform
  gravity::GravityOptions self_gravity{};          ///< for Kind::self (direct or tree, G, theta, order)
};

/// Everything one step needs to know besides the model and the state.
struct StepOptions {
  IntegratorOptions integrator{};  ///< h and theta
  DetectionOptions detection{};    ///< alert distance
  SolverOptions solver{};          ///< NLGS settings
  GravitySettings gravity{};       ///< external field
};

/// The stages of a step, in order, for timing reports.
enum class Stage { external_forces, free_velocity, broad_phase, narrow_phase, match_contacts, solver_preparation,
                   nlgs_sweeps, update_positions, count };
/// Printable name of a stage.
std::string_view stage_name(Stage stage);

/// What a step did.
struct StepReport {
  std::size_t contacts = 0;          ///< contact points found (gap < alert distance)
  SolverStats solver{};              ///< iterations, residual
  std::array<double, static_cast<std::size_t>(Stage::count)> stage_seconds{};  ///< wall time per stage
};

/// Data carried from one step to the next besides the state: last step's contacts (warm start)
/// and the detection memory. A checkpoint saves it with the state.
struct StepWorkspace {
  ContactList contacts;              ///< this step's contacts, last step's on entry
  DetectionMemory detection_memory;  ///< common-plane normals of persistent pairs
  std::vector<Vec3> force;           ///< scratch: external force per body
  BodyVelocities velocity;           ///< scratch: free, then end-of-step velocities
};

/// Advances `state` by one step of the Moreau-Jean theta-method.
StepReport step(const Model& model, State& state, StepWorkspace& workspace, const StepOptions& options);

}  // namespace rubble
