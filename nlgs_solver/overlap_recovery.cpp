#include "nlgs_solver/overlap_recovery.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rubble {
namespace {

/// One contact of the position-level problem: normal direction only, no friction.
struct Row {
  std::size_t a = 0, b = 0;
  Vec3 normal;
  Vec3 turn_a, turn_b;             ///< world I^-1 (arm x n): angular pseudo-velocity per unit normal impulse
  Vec3 lever_a, lever_b;           ///< arm x n: rate of the normal gap per unit angular velocity
  double normal_compliance = 0.0;  ///< W_nn
  double target = 0.0;             ///< c: the pseudo normal velocity asked for
  double impulse = 0.0;            ///< p >= 0
};

/// End-of-step gap predicted from the midpoint gap and the end-of-step normal velocity.
double end_gap(const Contact& c, const BodyVelocities& v, double drift) {
  const std::size_t a = c.id.body_a, b = c.id.body_b;
  const Vec3 relative = v.linear[b] + v.angular[b].cross(c.arm_b) - v.linear[a] - v.angular[a].cross(c.arm_a);
  return c.gap + drift * c.frame.col(0).dot(relative);
}

/// Allowed overlap of a contact: a fraction of the smaller bounding radius (a wall's is infinite
/// or its box's, so a grain-wall contact takes the grain's).
double allowed_overlap(const Model& model, const Contact& c, double fraction) {
  double radius = std::numeric_limits<double>::infinity();
  for (const std::size_t body : {std::size_t{c.id.body_a}, std::size_t{c.id.body_b}}) {
    if (!model.is_fixed(body)) radius = std::min(radius, model.bounding_radius[body]);
  }
  return std::isfinite(radius) ? fraction * radius : 0.0;
}

}  // namespace

OverlapRecoveryStats recover_overlaps(const Model& model, const State& state, const ContactList& contacts,
                                      const BodyVelocities& velocity, const IntegratorOptions& integrator,
                                      const OverlapRecoveryOptions& options, BodyVelocities& displacement_velocity) {
  OverlapRecoveryStats stats;
  displacement_velocity.linear.clear();
  displacement_velocity.angular.clear();
  if (options.fraction <= 0.0 || contacts.empty()) return stats;
  const double h = integrator.time_step;
  const double drift = integrator.theta * h;
  // Most steps have nothing to recover: one pass over the gaps decides.
  std::vector<double> excess(contacts.size());
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    const double overlap = -end_gap(contacts[k], velocity, drift);
    excess[k] = overlap - allowed_overlap(model, contacts[k], options.allowed_overlap);
    if (excess[k] > 0.0) {
      ++stats.overlapping;
      stats.deepest = std::max(stats.deepest, overlap);
    }
  }
  if (stats.overlapping == 0) return stats;

  // Every contact takes part, so that pushing one grain out of an overlap cannot push it into a
  // neighbour: a contact with room left (excess < 0) allows a pseudo approach of at most that room.
  std::vector<Row> rows(contacts.size());
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    const Contact& c = contacts[k];
    Row& row = rows[k];
    row.a = c.id.body_a;
    row.b = c.id.body_b;
    row.normal = c.frame.col(0);
    row.lever_a = c.arm_a.cross(row.normal);
    row.lever_b = c.arm_b.cross(row.normal);
    row.turn_a = model.is_fixed(row.a)
                     ? Vec3::Zero()
                     : Vec3(world_inverse_inertia(model, row.a, state.orientation[row.a]) * row.lever_a);
    row.turn_b = model.is_fixed(row.b)
                     ? Vec3::Zero()
                     : Vec3(world_inverse_inertia(model, row.b, state.orientation[row.b]) * row.lever_b);
    row.normal_compliance = c.delassus(0, 0);
    row.target = excess[k] > 0.0 ? std::min(options.fraction * excess[k] / h, options.max_velocity) : excess[k] / h;
  }
  const std::size_t n = model.body_count();
  displacement_velocity.linear.assign(n, Vec3::Zero());
  displacement_velocity.angular.assign(n, Vec3::Zero());
  Vec3* linear = displacement_velocity.linear.data();
  Vec3* angular = displacement_velocity.angular.data();
  double largest_target = 0.0;
  for (const Row& row : rows) largest_target = std::max(largest_target, row.target);
  // Projected Gauss-Seidel on the normal impulses; stops when no impulse changes the velocity it
  // acts on by more than 1e-6 of the largest target.
  for (stats.sweeps = 1; stats.sweeps <= options.max_sweeps; ++stats.sweeps) {
    double largest_change = 0.0;
    for (Row& row : rows) {
      if (!(row.normal_compliance > 0.0)) continue;
      const double normal_velocity = row.normal.dot(linear[row.b] - linear[row.a]) + row.lever_b.dot(angular[row.b]) -
                                     row.lever_a.dot(angular[row.a]);
      const double next = std::max(0.0, row.impulse - (normal_velocity - row.target) / row.normal_compliance);
      const double delta = next - row.impulse;
      if (delta == 0.0) continue;
      row.impulse = next;
      largest_change = std::max(largest_change, std::abs(delta) * row.normal_compliance);
      if (!model.is_fixed(row.b)) {
        linear[row.b] += (model.inverse_mass[row.b] * delta) * row.normal;
        angular[row.b] += delta * row.turn_b;
      }
      if (!model.is_fixed(row.a)) {
        linear[row.a] -= (model.inverse_mass[row.a] * delta) * row.normal;
        angular[row.a] -= delta * row.turn_a;
      }
    }
    if (largest_change <= 1e-6 * largest_target) break;
  }
  stats.sweeps = std::min(stats.sweeps, options.max_sweeps);
  return stats;
}

}  // namespace rubble
