// The gather and scatter of the sweeps' compact copy (compact_problem.hpp).
#include "nlgs_solver/compact_problem.hpp"

#include <Eigen/LU>  // Mat3::inverse

#include "core/huge_pages.hpp"
#include "nlgs_solver/prepare.hpp"

namespace rubble {
namespace {

/// Rolling and twisting resistance (ContactLaw::rolling_friction, twisting_friction) of the
/// compact problem's sphere contacts: sphere-sphere and sphere-wall pairs whose law has it (a
/// polyhedron resists rolling through its faces' several contact points: scenes refuse these laws
/// for pairs with a polyhedron material, nlgs_solver/README.md "Polyhedra"). r_eff = r_a r_b /
/// (r_a + r_b), a sphere's own radius against a wall; the angular compliance a = 1/I_a + 1/I_b
/// of the moving spheres (isotropic). The angular impulses start from the contacts' carried ones
/// (Contact::angular_impulse: last step's, warm start), applied by warm_start_rotations.
void gather_rotations(const Model& model, const SweepPlan& plan, const ContactList& contacts, CompactProblem& out) {
  out.rotation_of_point.assign(plan.order.size(), CompactProblem::no_rotation);
  for (std::size_t p = 0; p < plan.order.size(); ++p) {
    const Contact& c = contacts[plan.order[p]];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    const ContactLaw& law = model.contact_laws.get(model.material[a], model.material[b]);
    if (!law.resists_rotation()) continue;
    double compliance = 0.0;
    bool polyhedron = false;
    for (const std::size_t body : {a, b}) {
      if (model.is_fixed(body)) continue;
      if (model.shape_kind[body] != ShapeKind::sphere) polyhedron = true;
      compliance += 1.0 / model.principal_inertia[body].x();
    }
    if (polyhedron || compliance == 0.0) continue;
    const double reduced = reduced_radius(model, a, b);
    out.rotation_of_point[p] = static_cast<std::uint32_t>(out.rotation.size());
    out.rotation.push_back(
        {compliance, law.twisting_friction * reduced, law.rolling_friction * reduced, reduced, c.angular_impulse});
  }
}

/// Tangential restitution (ContactLaw::tangential_restitution): each point's tangential target
/// -e_t u_t-, u_t- the tangential part of the contact point's relative velocity at t_n (the
/// state's velocities, as Contact::normal_velocity_before for e_n).
void gather_tangential_targets(const Model& model, const State& state, const SweepPlan& plan,
                               const ContactList& contacts, CompactProblem& out) {
  out.tangential_target.assign(plan.order.size(), Vec2::Zero());
  for (std::size_t p = 0; p < plan.order.size(); ++p) {
    const Contact& c = contacts[plan.order[p]];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    const double restitution = model.contact_laws.get(model.material[a], model.material[b]).tangential_restitution;
    if (restitution == 0.0) continue;
    const Vec3 before = c.frame.transpose() * contact_relative_velocity(c, state.velocity, state.angular_velocity);
    out.tangential_target[p] = -restitution * Vec2(before.y(), before.z());
  }
}

/// The local numbering of the bodies: the plan's moving bodies in Morton order, then the walls in
/// the order the contacts meet them (a serial pass over the ids). Returns each model body's local
/// index (or max() for bodies of no contact) and fills out.body_id.
std::vector<std::uint32_t> number_bodies(const Model& model, const SweepPlan& plan, const ContactList& contacts,
                                         CompactProblem& out) {
  constexpr auto none = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> local(model.body_count(), none);
  auto add_body = [&](std::size_t body) {
    local[body] = static_cast<std::uint32_t>(out.body_id.size());
    out.body_id.push_back(body);
  };
  // The moving bodies plus room for every wall: no doubling of the arrays.
  std::size_t fixed_bodies = 0;
  for (std::size_t body = 0; body < model.body_count(); ++body) fixed_bodies += model.is_fixed(body) ? 1 : 0;
  out.body_id.reserve(plan.body_order.size() + fixed_bodies);
  for (const std::size_t body : plan.body_order) add_body(body);
  for (const std::size_t k : plan.order) {
    const Contact& c = contacts[k];
    if (local[c.id.body_a] == none) add_body(c.id.body_a);  // walls
    if (local[c.id.body_b] == none) add_body(c.id.body_b);
  }
  return local;
}

}  // namespace

CompactProblem gather_compact_problem(const Model& model, const State& state, const SweepPlan& plan,
                                      const ContactList& contacts, const BodyVelocities& velocity, bool parallel) {
  CompactProblem out;
  const std::vector<std::uint32_t> local = number_bodies(model, plan, contacts, out);
  out.bodies.resize(out.body_id.size());
  out.points.reserve(plan.order.size());
  advise_huge_pages(out.points.data(), plan.order.size() * sizeof(CompactProblem::Point));  // huge_pages.hpp
  out.points.resize(plan.order.size());
  out.drift.resize(out.body_id.size());
  out.watch.resize(plan.order.size());
  const auto bodies = static_cast<std::ptrdiff_t>(out.body_id.size());
  const auto n = static_cast<std::ptrdiff_t>(plan.order.size());
#pragma omp parallel if (parallel)
  {
#pragma omp for schedule(static) nowait
    for (std::ptrdiff_t i = 0; i < bodies; ++i) {
      const std::size_t body = out.body_id[static_cast<std::size_t>(i)];
      out.bodies[static_cast<std::size_t>(i)] = {velocity.linear[body], velocity.angular[body],
                                                 world_inverse_inertia(model, body, state.orientation[body]),
                                                 model.inverse_mass[body]};
    }
#pragma omp for schedule(static) nowait
    for (std::ptrdiff_t i = 0; i < n; ++i) {
      const auto p = static_cast<std::size_t>(i);
      const Contact& c = contacts[plan.order[p]];
      out.points[p] = {c.frame,
                       c.delassus,
                       c.delassus.inverse(),
                       c.arm_a,
                       c.arm_b,
                       c.impulse,
                       c.friction_coefficient,
                       c.normal_velocity_target,
                       local[c.id.body_a],
                       local[c.id.body_b]};
    }
  }
  if (model.contact_laws.any_resists_rotation()) gather_rotations(model, plan, contacts, out);
  if (model.contact_laws.any_tangential_restitution()) gather_tangential_targets(model, state, plan, contacts, out);
  return out;
}

void scatter_compact_problem(const Model& model, const SweepPlan& plan, const CompactProblem& compact,
                             ContactList& contacts, BodyVelocities& velocity, bool parallel) {
  const auto n = static_cast<std::ptrdiff_t>(plan.order.size());
  const auto bodies = static_cast<std::ptrdiff_t>(compact.bodies.size());
#pragma omp parallel if (parallel)
  {
#pragma omp for schedule(static) nowait
    for (std::ptrdiff_t p = 0; p < n; ++p) {
      contacts[plan.order[static_cast<std::size_t>(p)]].impulse = compact.points[static_cast<std::size_t>(p)].impulse;
    }
#pragma omp for schedule(static) nowait
    for (std::ptrdiff_t i = 0; i < bodies; ++i) {
      const std::size_t body = compact.body_id[static_cast<std::size_t>(i)];
      if (model.is_fixed(body)) continue;
      velocity.linear[body] = compact.bodies[static_cast<std::size_t>(i)].linear;
      velocity.angular[body] = compact.bodies[static_cast<std::size_t>(i)].angular;
    }
  }
  // The rotation blocks' angular impulses, for the next step's warm start and the checkpoints
  // (contacts without a block keep the zero they were detected with).
  for (std::size_t p = 0; p < compact.rotation_of_point.size(); ++p) {
    const std::uint32_t r = compact.rotation_of_point[p];
    if (r != CompactProblem::no_rotation) contacts[plan.order[p]].angular_impulse = compact.rotation[r].impulse;
  }
}

void warm_start_rotations(CompactProblem& compact) {
  for (std::size_t p = 0; p < compact.rotation_of_point.size(); ++p) {
    const std::uint32_t index = compact.rotation_of_point[p];
    if (index == CompactProblem::no_rotation) continue;
    CompactProblem::Rotation& r = compact.rotation[index];
    const CompactProblem::Point& c = compact.points[p];
    r.impulse = CompactProblem::project_onto_rotation_bounds(r.impulse, r, std::max(c.impulse.x(), 0.0));
    if (r.impulse != Vec3::Zero()) compact.apply_angular_impulse_change(p, c.frame * r.impulse);
  }
}

}  // namespace rubble
