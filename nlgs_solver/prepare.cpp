// The preparation of a step's contacts (LMGC90's "prep_nlgs"): each contact's arms, Delassus
// block W_kk = H_k^T M^-1 H_k from the bodies' inverse mass and world inverse inertia, its law,
// its normal target velocity b and its cohesive impulse. Nothing here depends on the sweep order.
#include "nlgs_solver/prepare.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "core/parallel.hpp"
#include "nlgs_solver/nlgs.hpp"

namespace rubble {
namespace {

/// Normal velocity target b of the unilateral condition 0 <= r_n _|_ U_n - b >= 0, for a contact
/// detected at the midpoint configuration q_m (gap g_m), whose gap at the end of the step is
/// g_m + theta h U_n (integrator.hpp). b_gap = -g_m / (theta h) is the velocity that just closes it.
/// - Open contact (the free motion keeps the gap open at the end of the step): b = b_gap, so a
///   contact pushed by others still cannot cross the gap (r = 0 otherwise).
/// - Closing or closed contact (LMGC90's predicted-gap activation): Newton's impact law
///   U_n >= -e_n U_n^- (Moreau 1988; Jean 1999) when it asks for a rebound; otherwise (e_n = 0, or
///   no approach at the start of the step) the gap-aware target min(b_gap, 0): a grain that
///   reaches contact inside the step may approach at the speed that just closes the gap, instead
///   of stopping short (b = 0) or, once overlapping, being pushed out (b > 0). An existing overlap
///   is never turned into a separating velocity: overlap_recovery.hpp removes it by displacement.
double normal_velocity_target(const Contact& c, double free_normal_velocity, const IntegratorOptions& integrator) {
  const double drift = integrator.theta * integrator.time_step;
  const double closing_velocity = -c.gap / drift;
  if (c.gap + drift * free_normal_velocity > 0.0) return closing_velocity;
  const double rebound = c.normal_restitution * std::max(-c.normal_velocity_before, 0.0);
  return rebound > 0.0 ? rebound : std::min(closing_velocity, 0.0);
}

/// Every body's inverse inertia in the world frame at the start of the step (one per body, so
/// that a body's many contacts do not each rotate its inertia).
std::vector<Mat3> world_inverse_inertias(const Model& model, const State& state) {
  std::vector<Mat3> result(model.body_count());
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(model.body_count());
#pragma omp parallel for schedule(static) if (n >= min_parallel_items)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto b = static_cast<std::size_t>(i);
    result[b] = world_inverse_inertia(model, b, state.orientation[b]);
  }
  return result;
}

/// K = m^-1 I - [arm]x I^-1 [arm]x: the point's velocity change per unit impulse at that point.
Mat3 point_compliance(double inverse_mass, const Mat3& inverse_inertia, const Vec3& arm) {
  const Mat3 cross = skew(arm);
  return inverse_mass * Mat3::Identity() - cross * inverse_inertia * cross;
}

/// Per contact point, c = F_c h / m: the cohesive impulse of its pair's law (ContactLaw::cohesion
/// plus 2 pi W r_eff) shared by the pair's m points, so that a pair's pull-off force does not
/// depend on how many points the detection gives a face-on-face contact. Cohesion holds while the
/// gap is at most 1e-3 of the smaller bounding radius (the overlap recovery's allowed depth): a
/// bond at rest keeps a gap of round-off size, either sign; a pair pulled apart beyond that range
/// has broken (a short-range bond, as van der Waals forces are).
std::vector<double> cohesive_impulses(const Model& model, const ContactList& contacts, double time_step) {
  std::vector<double> out(contacts.size(), 0.0);
  // Contacts are sorted by id: the points of a pair are consecutive.
  for (std::size_t first = 0; first < contacts.size();) {
    const std::size_t a = contacts[first].id.body_a, b = contacts[first].id.body_b;
    std::size_t last = first;
    while (last < contacts.size() && contacts[last].id.body_a == a && contacts[last].id.body_b == b) ++last;
    const ContactLaw& law = model.contact_laws.get(model.material[a], model.material[b]);
    if (law.cohesive()) {
      const double force = law.cohesion + 2.0 * std::numbers::pi * law.work_of_adhesion * reduced_radius(model, a, b);
      const double range = 1e-3 * std::min(model.bounding_radius[a], model.bounding_radius[b]);
      const double per_point = force * time_step / static_cast<double>(last - first);
      for (std::size_t k = first; k < last; ++k) out[k] = contacts[k].gap <= range ? per_point : 0.0;
    }
    first = last;
  }
  return out;
}

}  // namespace

double reduced_radius(const Model& model, std::size_t a, std::size_t b) {
  const auto radius = [&](std::size_t body) { return std::cbrt(3.0 * model.volume[body] / (4.0 * std::numbers::pi)); };
  if (model.is_fixed(a)) return radius(b);
  if (model.is_fixed(b)) return radius(a);
  const double ra = radius(a), rb = radius(b);
  return ra * rb / (ra + rb);
}

void prepare_contacts(const Model& model, const State& state, const BodyVelocities& free_velocity,
                      const IntegratorOptions& integrator, const SolverOptions& options, ContactList& contacts) {
  const std::vector<Mat3> inverse_inertia = world_inverse_inertias(model, state);
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(contacts.size());
  const std::vector<double> cohesive_impulse = model.contact_laws.any_cohesive()
                                                   ? cohesive_impulses(model, contacts, integrator.time_step)
                                                   : std::vector<double>();
#pragma omp parallel for schedule(static) if (n >= min_parallel_items)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    Contact& c = contacts[static_cast<std::size_t>(i)];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    c.arm_a = c.point - state.position[a];
    c.arm_b = c.point - state.position[b];
    const Mat3 compliance = point_compliance(model.inverse_mass[a], inverse_inertia[a], c.arm_a) +
                            point_compliance(model.inverse_mass[b], inverse_inertia[b], c.arm_b);
    c.delassus = c.frame.transpose() * compliance * c.frame;
    const ContactLaw& law = model.contact_laws.get(model.material[a], model.material[b]);
    c.friction_coefficient = law.friction_coefficient;
    c.normal_restitution = law.normal_restitution;
    const Vec3 normal = c.frame.col(0);
    c.normal_velocity_before = normal.dot(contact_relative_velocity(c, state.velocity, state.angular_velocity));
    const double free_normal = normal.dot(contact_relative_velocity(c, free_velocity.linear, free_velocity.angular));
    c.normal_velocity_target = normal_velocity_target(c, free_normal, integrator);
    c.cohesive_impulse = cohesive_impulse.empty() ? 0.0 : cohesive_impulse[static_cast<std::size_t>(i)];
    if (!options.warm_start) c.impulse = Vec3::Zero();
  }
}

}  // namespace rubble
