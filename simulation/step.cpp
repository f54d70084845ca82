#include "simulation/step.hpp"

#include <chrono>
#include <cmath>
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

/// Self-gravity acceleration of every body (zero for fixed bodies): point masses at the grains'
/// centres of mass (the LMGC90 accretion paper, sec. 2.3), by direct sum or tree. Returns the potential energy of the
/// grains, 1/2 sum m_i phi_i, from the same evaluation.
double self_gravity_accelerations(const Model& model, const State& state, const gravity::GravityOptions& options,
                                  std::vector<Vec3>& acceleration_out) {
  std::vector<std::size_t> grains;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_fixed(b)) grains.push_back(b);
  }
  std::vector<double> positions(3 * grains.size()), masses(grains.size());
  for (std::size_t k = 0; k < grains.size(); ++k) {
    for (int i = 0; i < 3; ++i) positions[3 * k + static_cast<std::size_t>(i)] = state.position[grains[k]][i];
    masses[k] = model.mass[grains[k]];
  }
  std::vector<double> acceleration(3 * grains.size()), potential(grains.size());
  gravity::compute_field(options, positions, masses, acceleration, potential);
  acceleration_out.assign(model.body_count(), Vec3::Zero());
  double energy = 0.0;
  for (std::size_t k = 0; k < grains.size(); ++k) {
    acceleration_out[grains[k]] = Vec3(acceleration[3 * k], acceleration[3 * k + 1], acceleration[3 * k + 2]);
    energy += 0.5 * masses[k] * potential[k];
  }
  return energy;
}

/// Work of the external forces over the displacement `scale` * `velocity` of every body, J.
double work_of_forces(const Model& model, const std::vector<Vec3>& force, const std::vector<Vec3>& velocity,
                      double scale) {
  double work = 0.0;
  if (velocity.empty()) return work;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_fixed(b)) work += force[b].dot(velocity[b]);
  }
  return scale * work;
}

/// Stage 2: external forces on every body at the midpoint configuration q_m (gravity; walls get
/// none). With evaluate_every = k > 1 the self-gravity field is evaluated at the midpoints of steps
/// n, n+k, ... and held in between: the grains' forces stay m a(q_m of step n) for k steps. The simplest multiple time
/// step scheme: its error in the acceleration used is a(t_n) - a(t) = O((t - t_n) |da/dt|), i.e.
/// O(k h |da/dt|) at worst per step, first order in k h (a time-interpolated or impulse (r-RESPA,
/// Tuckerman et al. 1992) scheme would be second order but needs the field at two times or a
/// symplectic split). It pays where the field changes slowly against the contact time step: a
/// cloud's free-fall time is ~1/sqrt(G rho) while h is set by grain travel per step.
/// Returns the gravitational potential energy of the grains at q_m, or nothing when a held
/// self-gravity field was used (it was evaluated at an earlier step).
std::optional<double> compute_external_forces(const Model& model, const State& state, const GravitySettings& gravity,
                                              StepWorkspace& workspace) {
  std::vector<Vec3>& force = workspace.force;
  force.assign(model.body_count(), Vec3::Zero());
  double potential = 0.0;
  switch (gravity.kind) {
    case GravitySettings::Kind::none:
      return potential;
    case GravitySettings::Kind::uniform:
      for (std::size_t b = 0; b < model.body_count(); ++b) {
        force[b] = model.mass[b] * gravity.acceleration;
        if (!model.is_fixed(b)) potential -= force[b].dot(state.position[b]);
      }
      return potential;
    case GravitySettings::Kind::central:
      for (std::size_t b = 0; b < model.body_count(); ++b) {
        if (model.is_fixed(b)) continue;
        force[b] = model.mass[b] * central_acceleration(gravity.central, state.position[b]);
        const double r2 = (state.position[b] - gravity.central.centre).squaredNorm() +
                          gravity.central.softening * gravity.central.softening;
        if (r2 > 0.0) potential -= gravity.central.G * gravity.central.mass * model.mass[b] / std::sqrt(r2);
      }
      return potential;
    case GravitySettings::Kind::self: {
      if (gravity.evaluate_every <= 1) {
        // Every step: no field is held (and a checkpoint carries none).
        workspace.carry.held_gravity.clear();
        workspace.carry.held_gravity_step = -1;
        std::vector<Vec3> acceleration;
        potential = self_gravity_accelerations(model, state, gravity.self_gravity, acceleration);
        for (std::size_t b = 0; b < model.body_count(); ++b) {
          if (!model.is_fixed(b)) force[b] = model.mass[b] * acceleration[b];
        }
        return potential;
      }
      StepCarry& carry = workspace.carry;
      const bool stale = carry.held_gravity.size() != model.body_count() || carry.held_gravity_step < 0 ||
                         state.step < carry.held_gravity_step ||
                         state.step - carry.held_gravity_step >= gravity.evaluate_every;
      std::optional<double> evaluated;
      if (stale) {
        evaluated = self_gravity_accelerations(model, state, gravity.self_gravity, carry.held_gravity);
        carry.held_gravity_step = state.step;
      }
      for (std::size_t b = 0; b < model.body_count(); ++b) {
        if (!model.is_fixed(b)) force[b] = model.mass[b] * carry.held_gravity[b];
      }
      return evaluated;
    }
  }
  return potential;
}

}  // namespace

Vec3 central_acceleration(const CentralField& field, const Vec3& position) {
  const Vec3 offset = position - field.centre;
  const double r2 = offset.squaredNorm() + field.softening * field.softening;
  if (!(r2 > 0.0)) return Vec3::Zero();  // at the centre of an unsoftened field: by symmetry, no pull
  return (-field.G * field.mass / (r2 * std::sqrt(r2))) * offset;
}

double gravitational_potential_energy(const Model& model, const State& state, const GravitySettings& gravity) {
  if (gravity.kind == GravitySettings::Kind::self) {
    std::vector<Vec3> unused;
    return self_gravity_accelerations(model, state, gravity.self_gravity, unused);
  }
  StepWorkspace scratch;
  return compute_external_forces(model, state, gravity, scratch).value_or(0.0);
}

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
  const std::optional<double> potential_at_midpoint = compute_external_forces(model, state, options.gravity, workspace);
  // Work of these forces from q_n to q_m (for the energy monitor when the field is held).
  const double work_to_midpoint =
      work_of_forces(model, workspace.force, state.velocity, (1.0 - integrator.theta) * integrator.time_step);
  timer.finish(Stage::external_forces);

  // 3. free_velocity: v_free = v_n + h M^-1 f(q_m) (+ implicit gyroscopic term).
  compute_free_velocity(model, state, workspace.force, {}, integrator, workspace.velocity);
  timer.finish(Stage::free_velocity);

  // 4. store_impulses: warm start needs of last step's contacts only their ids and world impulses
  // (40 of 304 bytes a point): keep those and free the list before this step's is built, so that
  // the two full lists are never alive together (at 1e5 spheres that was the run's peak memory).
  std::vector<CarriedImpulse> carried;
  if (options.solver.warm_start) carried = impulses_to_carry(workspace.carry.contacts);
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
  std::vector<CarriedImpulse>().swap(carried);
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
