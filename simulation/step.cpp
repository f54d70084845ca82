#include "simulation/step.hpp"

#include <chrono>
#include <optional>

namespace rubble {
namespace {

using Clock = std::chrono::steady_clock;

/// Times a stage into the report.
class StageTimer {
 public:
  explicit StageTimer(StepReport& report) : report_(report), start_(Clock::now()) {}
  void restart() { start_ = Clock::now(); }
  void finish(Stage stage) {
    const auto now = Clock::now();
    report_.stage_seconds[static_cast<std::size_t>(stage)] += std::chrono::duration<double>(now - start_).count();
    start_ = now;
  }

 private:
  StepReport& report_;
  Clock::time_point start_;
};

}  // namespace

std::string_view stage_name(Stage stage) {
  switch (stage) {
    case Stage::drift_to_midpoint:
      return "drift_to_midpoint";
    case Stage::external_forces:
      return "external_forces";
    case Stage::free_velocity:
      return "free_velocity";
    case Stage::store_impulses:
      return "store_impulses";
    case Stage::broad_phase:
      return "broad_phase";
    case Stage::narrow_phase:
      return "narrow_phase";
    case Stage::match_contacts:
      return "match_contacts";
    case Stage::solver_preparation:
      return "solver_preparation";
    case Stage::nlgs_sweeps:
      return "nlgs_sweeps";
    case Stage::overlap_recovery:
      return "overlap_recovery";
    case Stage::finish_step:
      return "finish_step";
    case Stage::count:
      break;
  }
  return "unknown";
}

StepReport step(const Model& model, State& state, StepWorkspace& workspace, const StepOptions& options) {
  StepReport report;
  StageTimer timer(report);
  const IntegratorOptions& integrator = options.integrator;

  // 1. drift_to_midpoint: q_m = q_n + (1 - theta) h v_n; forces and contacts are taken there.
  drift_to_midpoint(model, integrator, state);
  timer.finish(Stage::drift_to_midpoint);

  // 2. external_forces: gravity (uniform, central, or self-gravity, possibly held) at q_m.
  const std::optional<double> potential_at_midpoint =
      compute_external_forces(model, state, options.gravity, workspace.carry, workspace.self_gravity, workspace.force);
  // Work of these forces from q_n to q_m (for the energy monitor when the field is held).
  const double work_to_midpoint =
      work_of_forces(model, workspace.force, state.velocity, (1.0 - integrator.theta) * integrator.time_step);
  timer.finish(Stage::external_forces);

  // 3. free_velocity: v_free = v_n + h M^-1 f(q_m) (+ implicit gyroscopic term).
  compute_free_velocity(model, state, workspace.force, {}, integrator, workspace.velocity);
  timer.finish(Stage::free_velocity);

  // 4. store_impulses: warm start needs of last step's contacts only their ids and world impulses
  // (40 of 336 bytes a point): keep those and free the list before this step's is built, so that
  // the two full lists are never alive together (at 1e5 spheres that was the run's peak memory).
  // Rolling and twisting resistance's angular impulses too, only when some law has it.
  std::vector<CarriedImpulse> carried;
  std::vector<Vec3> carried_angular;
  if (options.solver.warm_start) carried = impulses_to_carry(workspace.carry.contacts);
  if (options.solver.warm_start && model.contact_laws.any_resists_rotation()) {
    carried_angular = angular_impulses_to_carry(workspace.carry.contacts);
  }
  ContactList().swap(workspace.carry.contacts);
  timer.finish(Stage::store_impulses);

  // 5. detect at q_m: broad phase, narrow phase -> contact points, frames, gaps.
  DetectionStats detection;
  ContactList contacts = detect_contacts(model, state, options.detection, workspace.carry.detection_memory, &detection);
  report.stage_seconds[static_cast<std::size_t>(Stage::broad_phase)] += detection.broad_phase_seconds;
  report.stage_seconds[static_cast<std::size_t>(Stage::narrow_phase)] += detection.narrow_phase_seconds;
  report.contacts = contacts.size();
  timer.restart();

  // 6. match_contacts: last step's impulses warm-start the persistent contacts.
  if (options.solver.warm_start) carry_impulses(carried, contacts);
  if (!carried_angular.empty()) carry_angular_impulses(carried, carried_angular, contacts);
  std::vector<CarriedImpulse>().swap(carried);
  std::vector<Vec3>().swap(carried_angular);
  workspace.carry.contacts = std::move(contacts);
  timer.finish(Stage::match_contacts);

  // 7. solve: Delassus blocks and targets, then NLGS sweeps; the velocity update
  // v_{n+1} = v_free + M^-1 H r happens inside the sweeps, contact by contact.
  prepare_contacts(model, state, workspace.velocity, integrator, options.solver, workspace.carry.contacts);
  timer.finish(Stage::solver_preparation);
  report.solver = solve_contacts(model, state, options.solver, workspace.carry.contacts, workspace.velocity);
  timer.finish(Stage::nlgs_sweeps);

  // 8. overlap_recovery: displacements (not velocities) that remove overlap left beyond the allowed depth.
  report.overlap = recover_overlaps(model, state, workspace.carry.contacts, workspace.velocity, integrator,
                                    options.solver.overlap_recovery, workspace.displacement_velocity);
  timer.finish(Stage::overlap_recovery);

  // 9. finish_step: q_{n+1} = q_m + theta h v_{n+1} (+ the recovery's displacement); t += h.
  // The potential energy at q_{n+1}: that at q_m minus the work of the forces from q_m on (exact
  // for a uniform field, O(h^2) otherwise, without accumulation); for a held field the work of the
  // whole step, to be taken from the previous step's value (StepReport::potential_energy).
  const double work_from_midpoint =
      work_of_forces(model, workspace.force, workspace.velocity.linear, integrator.theta * integrator.time_step) +
      work_of_forces(model, workspace.force, workspace.displacement_velocity.linear, integrator.time_step);
  if (potential_at_midpoint) {
    report.potential_energy = *potential_at_midpoint - work_from_midpoint;
  } else {
    report.potential_energy_known = false;
    report.work_of_held_field = work_to_midpoint + work_from_midpoint;
  }
  finish_step(model, integrator, workspace.velocity, workspace.displacement_velocity, state);
  timer.finish(Stage::finish_step);
  return report;
}

}  // namespace rubble
