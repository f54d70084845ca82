#include "simulation/external_forces.hpp"

#include <cmath>

namespace rubble {
namespace {

/// Self-gravity acceleration of every body (zero for fixed bodies) into acceleration_out: point
/// masses at the grains' centres of mass (the LMGC90 accretion paper, sec. 2.3), by direct sum or
/// tree. Returns the potential energy of the grains, 1/2 sum m_i phi_i, from the same evaluation.
double self_gravity_accelerations(const Model& model, const State& state, const gravity::GravityOptions& options,
                                  SelfGravityWorkspace& scratch, std::vector<Vec3>& acceleration_out) {
  std::vector<std::size_t>& grains = scratch.grains;
  grains.clear();
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_fixed(b)) grains.push_back(b);
  }
  std::vector<double>& positions = scratch.positions;
  std::vector<double>& masses = scratch.masses;
  positions.resize(3 * grains.size());
  masses.resize(grains.size());
  for (std::size_t k = 0; k < grains.size(); ++k) {
    for (int i = 0; i < 3; ++i) positions[3 * k + static_cast<std::size_t>(i)] = state.position[grains[k]][i];
    masses[k] = model.mass[grains[k]];
  }
  std::vector<double>& acceleration = scratch.acceleration;
  std::vector<double>& potential = scratch.potential;
  acceleration.resize(3 * grains.size());
  potential.resize(grains.size());
  gravity::compute_field(options, positions, masses, acceleration, potential, scratch.field);
  acceleration_out.assign(model.body_count(), Vec3::Zero());
  double energy = 0.0;
  for (std::size_t k = 0; k < grains.size(); ++k) {
    acceleration_out[grains[k]] = Vec3(acceleration[3 * k], acceleration[3 * k + 1], acceleration[3 * k + 2]);
    energy += 0.5 * masses[k] * potential[k];
  }
  return energy;
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
    SelfGravityWorkspace scratch;
    return self_gravity_accelerations(model, state, gravity.self_gravity, scratch, scratch.acceleration_per_body);
  }
  StepCarry carry;
  SelfGravityWorkspace scratch;
  std::vector<Vec3> force;
  return compute_external_forces(model, state, gravity, carry, scratch, force).value_or(0.0);
}

// With evaluate_every = k > 1 the self-gravity field is evaluated at the midpoints of steps
// n, n+k, ... and held in between: the grains' forces stay m a(q_m of step n) for k steps. The simplest multiple time
// step scheme: its error in the acceleration used is a(t_n) - a(t) = O((t - t_n) |da/dt|), i.e.
// O(k h |da/dt|) at worst per step, first order in k h (a time-interpolated or impulse (r-RESPA,
// Tuckerman et al. 1992) scheme would be second order but needs the field at two times or a
// symplectic split). It pays where the field changes slowly against the contact time step: a
// cloud's free-fall time is ~1/sqrt(G rho) while h is set by grain travel per step.
std::optional<double> compute_external_forces(const Model& model, const State& state, const GravitySettings& gravity,
                                              StepCarry& carry, SelfGravityWorkspace& scratch,
                                              std::vector<Vec3>& force) {
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
        carry.held_gravity.clear();
        carry.held_gravity_step = -1;
        std::vector<Vec3>& acceleration = scratch.acceleration_per_body;
        potential = self_gravity_accelerations(model, state, gravity.self_gravity, scratch, acceleration);
        for (std::size_t b = 0; b < model.body_count(); ++b) {
          if (!model.is_fixed(b)) force[b] = model.mass[b] * acceleration[b];
        }
        return potential;
      }
      const bool stale = carry.held_gravity.size() != model.body_count() || carry.held_gravity_step < 0 ||
                         state.step < carry.held_gravity_step ||
                         state.step - carry.held_gravity_step >= gravity.evaluate_every;
      std::optional<double> evaluated;
      if (stale) {
        evaluated = self_gravity_accelerations(model, state, gravity.self_gravity, scratch, carry.held_gravity);
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

double work_of_forces(const Model& model, const std::vector<Vec3>& force, const std::vector<Vec3>& velocity,
                      double scale) {
  double work = 0.0;
  if (velocity.empty()) return work;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_fixed(b)) work += force[b].dot(velocity[b]);
  }
  return scale * work;
}

}  // namespace rubble
