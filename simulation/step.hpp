#pragma once
// One Moreau-Jean time step, as named stages in order (see step.cpp). This is the only place
// that calls every stage; no stage calls it.
#include <array>
#include <cstdint>
#include <string_view>

#include "contact_detection/detection.hpp"
#include "core/integrator.hpp"
#include "core/model.hpp"
#include "core/state.hpp"
#include "nlgs_solver/nlgs.hpp"
#include "simulation/external_forces.hpp"
#include "simulation/step_carry.hpp"

namespace rubble {

/// Everything one step needs to know besides the model and the state.
struct StepOptions {
  IntegratorOptions integrator{};  ///< h and theta
  DetectionOptions detection{};    ///< alert distance
  SolverOptions solver{};          ///< NLGS settings
  GravitySettings gravity{};       ///< external field
};

/// The stages of a step, in execution order (step.cpp), for timing reports.
enum class Stage {
  drift_to_midpoint,
  external_forces,
  free_velocity,
  store_impulses,
  broad_phase,
  narrow_phase,
  match_contacts,
  solver_preparation,
  nlgs_sweeps,
  overlap_recovery,
  finish_step,
  count
};
/// Printable name of a stage.
std::string_view stage_name(Stage stage);

/// What a step did.
struct StepReport {
  std::size_t contacts = 0;        ///< contact points found (gap < alert distance)
  SolverStats solver{};            ///< iterations, residual
  OverlapRecoveryStats overlap{};  ///< overlaps beyond the allowed depth, removed by displacement
  /// Gravitational potential energy of the grains at the end of the step, J (self-gravity: from
  /// the step's own evaluation at q_m, carried to q_{n+1} by the forces' work; uniform: -sum m g.x).
  /// Valid when potential_energy_known; otherwise the field was held (GravitySettings::
  /// evaluate_every) and the energy is the previous step's minus work_of_held_field.
  double potential_energy = 0.0;
  bool potential_energy_known = true;  ///< false on steps that used a held self-gravity field
  double work_of_held_field = 0.0;     ///< J, work of the held field's forces over the step
  std::array<double, static_cast<std::size_t>(Stage::count)> stage_seconds{};  ///< wall time per stage
};

/// What step() works with besides the model and the state: the data carried to the next step
/// (StepCarry, saved by a checkpoint) and the step's scratch arrays, rebuilt every step (kept here
/// only so that their memory is reused).
struct StepWorkspace {
  StepCarry carry;                       ///< last step's contacts on entry, this step's on return
  std::vector<Vec3> force;               ///< scratch: external force per body
  BodyVelocities velocity;               ///< scratch: free, then end-of-step velocities
  BodyVelocities displacement_velocity;  ///< scratch: the overlap recovery's pseudo-velocities (often empty)
  SelfGravityWorkspace self_gravity;     ///< scratch: self-gravity's arrays and tree
};

/// Advances `state` by one step of the Moreau-Jean theta-method in Moreau's midpoint form
/// (core/integrator.hpp): forces and contacts at q_m = q_n + (1 - theta) h v_n.
StepReport step(const Model& model, State& state, StepWorkspace& workspace, const StepOptions& options);

}  // namespace rubble
