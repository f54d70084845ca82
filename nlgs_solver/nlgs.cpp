#include "nlgs_solver/nlgs.hpp"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/parallel.hpp"
#include "nlgs_solver/coulomb.hpp"
#include "nlgs_solver/local_problem.hpp"
#include "nlgs_solver/sweep.hpp"

namespace rubble {
namespace {

using Clock = std::chrono::steady_clock;

/// The simulation's contact problem: W = H^T M^-1 H is never assembled; u_k is read off the two
/// bodies' current velocities and an impulse change is applied to them at once.
struct BodyCoupledProblem {
  const Model& model;
  ContactList& contacts;
  BodyVelocities& velocity;
  const std::vector<Mat3>& inverse_inertia_world;

  std::size_t size() const { return contacts.size(); }
  const Mat3& delassus(std::size_t k) const { return contacts[k].delassus; }
  double friction_coefficient(std::size_t k) const { return contacts[k].friction_coefficient; }
  Vec3& impulse(std::size_t k) { return contacts[k].impulse; }

  /// u = R^T (v_b + w_b x arm_b - v_a - w_a x arm_a) - b e_n: the target velocity b is folded in,
  /// so the law reads 0 <= r_n _|_ u_n >= 0.
  Vec3 local_velocity(std::size_t k) const {
    const Contact& c = contacts[k];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    const Vec3 relative = velocity.linear[b] + velocity.angular[b].cross(c.arm_b) - velocity.linear[a] -
                          velocity.angular[a].cross(c.arm_a);
    Vec3 u = c.frame.transpose() * relative;
    u.x() -= c.normal_velocity_target;
    return u;
  }

  void apply_impulse_change(std::size_t k, const Vec3& delta) {
    const Contact& c = contacts[k];
    const std::size_t a = c.id.body_a, b = c.id.body_b;
    const Vec3 p = c.frame * delta;  // world impulse on b; -p on a
    // Walls are never written: contacts of concurrent sweep groups may share a wall.
    if (!model.is_fixed(b)) {
      velocity.linear[b] += model.inverse_mass[b] * p;
      velocity.angular[b] += inverse_inertia_world[b] * c.arm_b.cross(p);
    }
    if (!model.is_fixed(a)) {
      velocity.linear[a] -= model.inverse_mass[a] * p;
      velocity.angular[a] -= inverse_inertia_world[a] * c.arm_a.cross(p);
    }
  }
};

/// The sweeps' own compact copy of the problem, in the plan's order (point p is contact
/// plan.order[p]; bodies in Morton order, then the walls): a sweep reads its contacts one after the
/// other in memory and the velocities of bodies near in space from nearby memory, instead of
/// hopping through the ContactList (sorted by body id) and the body arrays (numbered as the
/// generator placed the grains). The arithmetic is BodyCoupledProblem's, operation for operation,
/// so the iterate is the same to the bit.
struct CompactProblem {
  struct Point {
    Mat3 frame;
    Mat3 delassus;
    Vec3 arm_a, arm_b;
    Vec3 impulse;
    double friction_coefficient;
    double normal_velocity_target;
    std::uint32_t a, b;  // local body indices
  };
  struct Body {
    Vec3 linear, angular;
    Mat3 inverse_inertia;
    double inverse_mass;
  };
  /// Rolling and twisting resistance of a sphere contact (ContactLaw::rolling_friction,
  /// twisting_friction): the contact's angular block, solved after its force in each sweep.
  struct Rotation {
    double compliance;        // a: relative angular velocity per unit angular impulse (isotropic for spheres), 1/(kg m^2)
    double twist_bound;       // mu_t r_eff, m: bound on the twisting impulse per unit normal impulse
    double roll_bound;        // mu_r r_eff, m: bound on the rolling impulse per unit normal impulse
    double radius;            // r_eff, m: turns the block's residual into velocity units
    Vec3 impulse;             // (twist about n, roll about t, roll about s), N m s; from zero each step
  };
  static constexpr std::uint32_t no_rotation = std::numeric_limits<std::uint32_t>::max();
  std::vector<Point> points;
  std::vector<Body> bodies;
  std::vector<std::size_t> body_id;  // model index of each local body
  std::vector<std::uint32_t> rotation_of_point;  // per point, index into `rotation` (empty: no such law in the scene)
  std::vector<Rotation> rotation;

  std::size_t size() const { return points.size(); }
  const Mat3& delassus(std::size_t k) const { return points[k].delassus; }
  double friction_coefficient(std::size_t k) const { return points[k].friction_coefficient; }
  Vec3& impulse(std::size_t k) { return points[k].impulse; }

  Vec3 local_velocity(std::size_t k) const {
    const Point& c = points[k];
    const Body& a = bodies[c.a];
    const Body& b = bodies[c.b];
    const Vec3 relative = b.linear + b.angular.cross(c.arm_b) - a.linear - a.angular.cross(c.arm_a);
    Vec3 u = c.frame.transpose() * relative;
    u.x() -= c.normal_velocity_target;
    return u;
  }

  /// The angular impulse m of point k's rotation block that the law allows for the current
  /// relative angular velocity: the one that stops the relative rotation (m - omega / a),
  /// projected on |m_n| <= mu_t r_eff r_n and ||(m_t, m_s)|| <= mu_r r_eff r_n. For spheres the
  /// angular compliance is isotropic, so this projection is the exact solution of the block (the
  /// minimum of the block's kinetic energy over the bounds), as the force's local solver is exact.
  /// r_n is the normal impulse including cohesion (the shifted r~).
  Vec3 allowed_rotation_impulse(std::size_t k, const Rotation& rotation) const {
    const Point& c = points[k];
    const Vec3 omega = c.frame.transpose() * (bodies[c.b].angular - bodies[c.a].angular);
    const double normal = std::max(c.impulse.x(), 0.0);
    Vec3 m = rotation.impulse - omega / rotation.compliance;
    m.x() = std::clamp(m.x(), -rotation.twist_bound * normal, rotation.twist_bound * normal);
    const double roll = std::hypot(m.y(), m.z()), roll_limit = rotation.roll_bound * normal;
    if (roll > roll_limit) {
      m.y() *= roll_limit / roll;
      m.z() *= roll_limit / roll;
    }
    return m;
  }

  /// Residual of point k's rotation block, natural map m - P(m - omega / a) in velocity units
  /// (times a r_eff, as the force's W_nn), and its impulse term; zeros when it has none.
  std::pair<double, double> rotation_residual(std::size_t k) const {
    if (rotation_of_point.empty() || rotation_of_point[k] == no_rotation) return {0.0, 0.0};
    const Rotation& r = rotation[rotation_of_point[k]];
    const double scale = r.compliance * r.radius;
    return {(scale * (r.impulse - allowed_rotation_impulse(k, r))).squaredNorm(), (scale * r.impulse).squaredNorm()};
  }

  /// The sweep's rotation step of point k, right after the force's update (RotatingProblem).
  void rotation_step(std::size_t k, SweepResult& sums) {
    if (rotation_of_point[k] == no_rotation) return;
    Rotation& r = rotation[rotation_of_point[k]];
    const Vec3 next = allowed_rotation_impulse(k, r);
    const double scale = r.compliance * r.radius;
    sums.residual_squared += (scale * (r.impulse - next)).squaredNorm();
    sums.impulse_squared += (scale * next).squaredNorm();
    const Point& c = points[k];
    const Vec3 change = c.frame * (next - r.impulse);  // world angular impulse on b; -change on a
    r.impulse = next;
    Body& b = bodies[c.b];
    Body& a = bodies[c.a];
    if (b.inverse_mass != 0.0) b.angular += b.inverse_inertia * change;
    if (a.inverse_mass != 0.0) a.angular -= a.inverse_inertia * change;
  }

  void apply_impulse_change(std::size_t k, const Vec3& delta) {
    const Point& c = points[k];
    const Vec3 p = c.frame * delta;
    Body& b = bodies[c.b];
    Body& a = bodies[c.a];
    if (b.inverse_mass != 0.0) {  // Model::is_fixed
      b.linear += b.inverse_mass * p;
      b.angular += b.inverse_inertia * c.arm_b.cross(p);
    }
    if (a.inverse_mass != 0.0) {
      a.linear -= a.inverse_mass * p;
      a.angular -= a.inverse_inertia * c.arm_a.cross(p);
    }
  }
};

/// The compact problem with its rotation blocks: what the sweeps see when some contact resists
/// rolling or twisting (nlgs_sweep then calls resist_rotation after each force). A separate type,
/// so that the sweeps of a scene without such laws carry no per-contact test for them.
struct RotatingProblem {
  CompactProblem& compact;
  std::size_t size() const { return compact.size(); }
  const Mat3& delassus(std::size_t k) const { return compact.delassus(k); }
  double friction_coefficient(std::size_t k) const { return compact.friction_coefficient(k); }
  Vec3& impulse(std::size_t k) { return compact.impulse(k); }
  Vec3 local_velocity(std::size_t k) const { return compact.local_velocity(k); }
  void apply_impulse_change(std::size_t k, const Vec3& delta) { compact.apply_impulse_change(k, delta); }
  void resist_rotation(std::size_t k, SweepResult& sums) { compact.rotation_step(k, sums); }
};

/// Reduced radius r_eff = r_a r_b / (r_a + r_b) of a contact's bodies from their volume-equivalent
/// radii (a sphere's own radius), a grain's own radius against a wall: the radius the cohesive
/// pull-off force and the rolling and twisting bounds scale with.
double reduced_radius(const Model& model, std::size_t a, std::size_t b) {
  const auto radius = [&](std::size_t body) { return std::cbrt(3.0 * model.volume[body] / (4.0 * std::numbers::pi)); };
  if (model.is_fixed(a)) return radius(b);
  if (model.is_fixed(b)) return radius(a);
  const double ra = radius(a), rb = radius(b);
  return ra * rb / (ra + rb);
}

/// Rolling and twisting resistance (ContactLaw::rolling_friction, twisting_friction) of the
/// compact problem's sphere contacts: sphere-sphere and sphere-wall pairs whose law has it (a
/// polyhedron resists rolling through its faces' several contact points). r_eff = r_a r_b /
/// (r_a + r_b), a sphere's own radius against a wall; the angular compliance a = 1/I_a + 1/I_b
/// of the moving spheres (isotropic). The angular impulses start from zero each step.
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
    out.rotation.push_back({compliance, law.twisting_friction * reduced, law.rolling_friction * reduced, reduced, Vec3::Zero()});
  }
}

/// The compact copy: bodies in the plan's Morton order, then the walls in the order the contacts
/// meet them (a serial pass over the ids), then the bodies' and contact points' data filled
/// concurrently. Each body's world inverse inertia is computed here rather than copied (same
/// function, same value), so the solver needs its own array only when a polish may run.
CompactProblem gather_problem(const Model& model, const State& state, const SweepPlan& plan, const ContactList& contacts,
                              const BodyVelocities& velocity, bool parallel) {
  CompactProblem out;
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
  out.bodies.resize(out.body_id.size());
  out.points.resize(plan.order.size());
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
      out.points[p] = {c.frame, c.delassus, c.arm_a, c.arm_b, c.impulse, c.friction_coefficient, c.normal_velocity_target,
                       local[c.id.body_a], local[c.id.body_b]};
    }
  }
  if (model.contact_laws.any_resists_rotation()) gather_rotations(model, plan, contacts, out);
  return out;
}

/// Copies the compact problem's impulses and moving bodies' velocities back.
void scatter_problem(const Model& model, const SweepPlan& plan, const CompactProblem& compact, ContactList& contacts,
                     BodyVelocities& velocity, bool parallel) {
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
}

/// After the polish changed the impulses and velocities: refreshes the compact copy's.
void refresh_problem(const SweepPlan& plan, const ContactList& contacts, const BodyVelocities& velocity,
                     CompactProblem& compact) {
  for (std::size_t p = 0; p < plan.order.size(); ++p) compact.points[p].impulse = contacts[plan.order[p]].impulse;
  for (std::size_t i = 0; i < compact.bodies.size(); ++i) {
    compact.bodies[i].linear = velocity.linear[compact.body_id[i]];
    compact.bodies[i].angular = velocity.angular[compact.body_id[i]];
  }
}

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

/// Spreads the low 21 bits of x to every third bit (bit i goes to bit 3i), for Morton keys.
std::uint64_t spread_bits(std::uint64_t x) {
  x &= 0x1fffffULL;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

/// Morton (Z-order) keys of points quantised on 2^21 cells per axis of a cube: points near each
/// other in space mostly get near keys, so a sweep in key order reuses the bodies it just touched
/// (cache) and a contiguous key range is a compact region (few contacts on its boundary).
struct MortonGrid {
  Vec3 lower = Vec3::Zero();
  double cells_per_metre = 0.0;

  std::uint64_t key(const Vec3& p) const {
    constexpr double top = 2097151.0;  // 2^21 - 1
    std::uint64_t key = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const double cell = std::clamp((p[axis] - lower[axis]) * cells_per_metre, 0.0, top);
      key |= spread_bits(static_cast<std::uint64_t>(cell)) << axis;
    }
    return key;
  }
};

/// Node of the binary tree over the blocks [first, last): split in the middle.
struct BlockNode {
  std::size_t first = 0, last = 0;  ///< leaves (blocks) below this node
  int height = 0;                   ///< 0 for a leaf
  std::size_t left = 0, right = 0;  ///< children (node indices) of an inner node
};

std::size_t build_block_tree(std::vector<BlockNode>& nodes, std::size_t first, std::size_t last) {
  const std::size_t self = nodes.size();
  nodes.push_back({first, last, 0, 0, 0});
  if (last - first > 1) {
    const std::size_t middle = first + (last - first) / 2;
    const std::size_t left = build_block_tree(nodes, first, middle);
    const std::size_t right = build_block_tree(nodes, middle, last);
    nodes[self].left = left;
    nodes[self].right = right;
    nodes[self].height = 1 + std::max(nodes[left].height, nodes[right].height);
  }
  return self;
}

/// The lowest node whose blocks include both block i and block j.
std::size_t common_node(const std::vector<BlockNode>& nodes, std::size_t i, std::size_t j) {
  std::size_t node = 0;
  while (nodes[node].last - nodes[node].first > 1) {
    const std::size_t middle = nodes[nodes[node].left].last;
    if (i < middle && j < middle) node = nodes[node].left;
    else if (i >= middle && j >= middle) node = nodes[node].right;
    else break;
  }
  return node;
}

/// Calls visit(g) once for every group of the plan, each group after both subtrees below it.
/// Serially: group after group (phase by phase). In parallel (one OpenMP team, no barrier inside):
/// the threads take the leaves' groups in contiguous runs (a static schedule: with 2 threads and
/// 16 blocks, thread 0 holds blocks 0-7 and thread 1 blocks 8-15, one subtree each, so only the
/// root's group waits for the other thread; a dynamic schedule hands the last leaves out together
/// and leaves one thread to climb the whole path from the last leaf to the root alone, ~12% of the
/// contacts of the mixed deposit), and whoever finishes the second child of a tree node visits
/// that node's group next, and so on up to the root (an atomic arrival count per node; its
/// acquire-release ordering makes the sibling's velocity writes visible). Groups that may run
/// concurrently share no moving body (walls are never written), so every contact is updated from
/// the same data as in the serial order: the result does not depend on the thread count.
/// (A barrier per phase instead costs 5 synchronisations per sweep; on a loaded machine each is a
/// scheduler time slice.)
template <class Visit>
void visit_groups(const SweepPlan& plan, bool parallel, const Visit& visit) {
  const std::size_t groups = plan.group_start.size() - 1;
  if (!parallel) {
    for (std::size_t g = 0; g < groups; ++g) visit(g);
    return;
  }
  std::vector<std::atomic<int>> arrivals(groups);
  for (auto& count : arrivals) count.store(0, std::memory_order_relaxed);
  const auto leaves = static_cast<std::ptrdiff_t>(plan.phase_start[1]);
#pragma omp parallel
  {
#pragma omp for schedule(static) nowait
    for (std::ptrdiff_t leaf = 0; leaf < leaves; ++leaf) {
      std::size_t g = static_cast<std::size_t>(leaf);
      visit(g);
      // Climb while this thread completed the second child of the parent.
      while (plan.parent_group[g] < groups) {
        g = plan.parent_group[g];
        if (arrivals[g].fetch_add(1, std::memory_order_acq_rel) == 0) break;  // the sibling's thread goes on
        visit(g);
      }
    }
  }
}

/// One sweep of the compact problem (point p = position p of the plan's order), group by group
/// (visit_groups). The groups' residual sums are added in group order, so the stopping test does
/// not depend on the thread count either. In parallel, `group_seconds` receives each group's own
/// sweep time (their sum is what the sweep costs on one thread), so the caller can tell when the
/// threads spend longer waiting for a core than working.
template <class Problem>
SweepResult planned_sweep(Problem& problem, const SweepPlan& plan, std::span<const std::size_t> order, double relaxation,
                          bool parallel, std::vector<SweepResult>& group_result, std::vector<double>& group_seconds) {
  const std::size_t groups = plan.group_start.size() - 1;
  group_result.assign(groups, SweepResult{});
  if (parallel) group_seconds.assign(groups, 0.0);
  visit_groups(plan, parallel, [&](std::size_t g) {
    const std::size_t first = plan.group_start[g], last = plan.group_start[g + 1];
    if (first == last) return;
    const auto begin = Clock::now();
    const std::span<const std::size_t> part(order.data() + first, last - first);
    group_result[g] = nlgs_sweep(problem, part, relaxation);
    if (parallel) group_seconds[g] = std::chrono::duration<double>(Clock::now() - begin).count();
  });
  SweepResult sum;
  for (const SweepResult& r : group_result) {
    sum.residual_squared += r.residual_squared;
    sum.impulse_squared += r.impulse_squared;
  }
  return sum;
}

/// The contacts' problem as explicit data for the Newton polish, in scaled impulses
/// r~_k = W_kk,nn r_k (velocity units), so that the polish's error measure (natural map with
/// rho = 1 on r~, u) is the sweeps' criterion (natural map with rho = W_nn on r, u):
/// u = W~ r~ + q with W~_kl = W_kl / d_l, and W_kl = R_k^T (sum over shared moving bodies of
/// s_k s_l K(arm_k, arm_l)) R_l, K(x, y) = m^-1 I - [x] I^-1 [y], s = +1 on the b side, -1 on a.
struct ScaledProblem {
  LocalProblem problem;
  std::vector<double> normal_compliance;  ///< d_k = W_kk,nn
};

ScaledProblem assemble_scaled_problem(const Model& model, const BodyCoupledProblem& coupled) {
  const ContactList& contacts = coupled.contacts;
  const std::size_t n = contacts.size();
  ScaledProblem out;
  out.normal_compliance.resize(n);
  for (std::size_t k = 0; k < n; ++k) out.normal_compliance[k] = contacts[k].delassus(0, 0);
  // Contacts of each moving body.
  std::vector<std::vector<std::size_t>> of_body(model.body_count());
  for (std::size_t k = 0; k < n; ++k) {
    if (!model.is_fixed(contacts[k].id.body_a)) of_body[contacts[k].id.body_a].push_back(k);
    if (!model.is_fixed(contacts[k].id.body_b)) of_body[contacts[k].id.body_b].push_back(k);
  }
  auto side = [&](const Contact& c, std::size_t body, Vec3& arm) {
    if (c.id.body_b == body) {
      arm = c.arm_b;
      return 1.0;
    }
    arm = c.arm_a;
    return -1.0;
  };
  SparseMatrix& W = out.problem.W;
  W.rows = W.columns = static_cast<int>(3 * n);
  W.row_start.assign(1, 0);
  std::vector<std::pair<std::size_t, Mat3>> row;  // (l, body-frame sum) for contact k
  for (std::size_t k = 0; k < n; ++k) {
    const Contact& ck = contacts[k];
    row.clear();
    for (const std::size_t body : {ck.id.body_a, ck.id.body_b}) {
      if (model.is_fixed(body)) continue;
      Vec3 arm_k, arm_l;
      const double sk = side(ck, body, arm_k);
      const Mat3& inverse_inertia = coupled.inverse_inertia_world[body];
      for (const std::size_t l : of_body[body]) {
        const double sl = side(contacts[l], body, arm_l);
        const Mat3 compliance = model.inverse_mass[body] * Mat3::Identity() - skew(arm_k) * inverse_inertia * skew(arm_l);
        row.emplace_back(l, sk * sl * compliance);
      }
    }
    std::sort(row.begin(), row.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    std::vector<std::pair<std::size_t, Mat3>> merged;
    for (const auto& [l, m] : row) {
      if (!merged.empty() && merged.back().first == l) merged.back().second += m;
      else merged.emplace_back(l, m);
    }
    for (auto& [l, m] : merged) m = ck.frame.transpose() * m * contacts[l].frame / out.normal_compliance[l];
    for (int i = 0; i < 3; ++i) {
      for (const auto& [l, m] : merged) {
        for (int j = 0; j < 3; ++j) {
          W.column.push_back(static_cast<int>(3 * l) + j);
          W.value.push_back(m(i, j));
        }
      }
      W.row_start.push_back(static_cast<int>(W.column.size()));
    }
  }
  out.problem.mu.resize(n);
  for (std::size_t k = 0; k < n; ++k) out.problem.mu[k] = contacts[k].friction_coefficient;
  return out;
}

/// One Newton polish of the current impulses (see SolverOptions::polish_after). On success the
/// impulses and the bodies' velocities hold the polished solution. Returns the Newton steps taken
/// and sets `converged` when the sweeps' criterion is met.
/// `tolerance` is on the FCLib measure of the whole problem (||F|| / ||q|| over every contact).
int polish_contacts(const Model& model, BodyCoupledProblem& coupled, const SolverOptions& options, double tolerance,
                    bool& converged) {
  ContactList& contacts = coupled.contacts;
  const std::size_t n = contacts.size();
  ScaledProblem scaled = assemble_scaled_problem(model, coupled);
  LocalProblem& problem = scaled.problem;
  std::vector<double> r(3 * n), u(3 * n);
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3 velocity = coupled.local_velocity(k);
    for (int i = 0; i < 3; ++i) {
      r[3 * k + static_cast<std::size_t>(i)] = scaled.normal_compliance[k] * contacts[k].impulse[i];
      u[3 * k + static_cast<std::size_t>(i)] = velocity[i];
    }
  }
  // q = u - W~ r~: the local velocities without any impulse.
  problem.q = u;
  for (int row = 0; row < problem.W.rows; ++row) {
    for (int e = problem.W.row_start[static_cast<std::size_t>(row)]; e < problem.W.row_start[static_cast<std::size_t>(row) + 1]; ++e) {
      problem.q[static_cast<std::size_t>(row)] -=
          problem.W.value[static_cast<std::size_t>(e)] * r[static_cast<std::size_t>(problem.W.column[static_cast<std::size_t>(e)])];
    }
  }
  LocalProblemOptions polish;
  polish.tolerance = tolerance;
  polish.polish_iterations = options.polish_iterations;
  double error = fclib_error(problem, r, u);
  const double before = error;
  const int steps = polish_solution(problem, polish, r, u, error);
  if (error < before) {
    for (std::size_t k = 0; k < n; ++k) {
      // Newton's iterate may sit a rounding error outside the cone; the impulse must not.
      const Vec3 next = project_onto_coulomb_cone(Vec3(r[3 * k], r[3 * k + 1], r[3 * k + 2]) / scaled.normal_compliance[k],
                                                  contacts[k].friction_coefficient);
      const Vec3 delta = next - contacts[k].impulse;
      contacts[k].impulse = next;
      coupled.apply_impulse_change(k, delta);
    }
  }
  converged = error <= tolerance;
  return steps;
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

void prepare_contacts(const Model& model, const State& state, const BodyVelocities& free_velocity,
                      const IntegratorOptions& integrator, const SolverOptions& options, ContactList& contacts) {
  const std::vector<Mat3> inverse_inertia = world_inverse_inertias(model, state);
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(contacts.size());
  const std::vector<double> cohesive_impulse =
      model.contact_laws.any_cohesive() ? cohesive_impulses(model, contacts, integrator.time_step) : std::vector<double>();
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
    c.normal_velocity_before = normal.dot(state.velocity[b] + state.angular_velocity[b].cross(c.arm_b) -
                                          state.velocity[a] - state.angular_velocity[a].cross(c.arm_a));
    const double free_normal = normal.dot(free_velocity.linear[b] + free_velocity.angular[b].cross(c.arm_b) -
                                          free_velocity.linear[a] - free_velocity.angular[a].cross(c.arm_a));
    c.normal_velocity_target = normal_velocity_target(c, free_normal, integrator);
    c.cohesive_impulse = cohesive_impulse.empty() ? 0.0 : cohesive_impulse[static_cast<std::size_t>(i)];
    if (!options.warm_start) c.impulse = Vec3::Zero();
  }
}

SweepPlan plan_sweep(const Model& model, const State& state, const ContactList& contacts, int block_count) {
  if (block_count < 1) {
    throw std::invalid_argument("plan_sweep: block_count must be at least 1, got " + std::to_string(block_count));
  }
  const auto blocks = static_cast<std::size_t>(block_count);
  // The moving bodies of the contacts, with the number of contact ends each carries (the weight
  // that balances the blocks).
  std::vector<std::size_t> block_of(model.body_count(), 0);
  std::vector<std::size_t> bodies;
  for (const Contact& c : contacts) {
    for (const std::size_t body : {std::size_t{c.id.body_a}, std::size_t{c.id.body_b}}) {
      if (model.is_fixed(body)) continue;
      if (block_of[body]++ == 0) bodies.push_back(body);
    }
  }
  // The grid: a cube around the moving bodies' centres and the contact points.
  MortonGrid grid;
  Vec3 lower = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 upper = -lower;
  for (const std::size_t body : bodies) {
    lower = lower.cwiseMin(state.position[body]);
    upper = upper.cwiseMax(state.position[body]);
  }
  for (const Contact& c : contacts) {
    lower = lower.cwiseMin(c.point);
    upper = upper.cwiseMax(c.point);
  }
  if (!contacts.empty()) {
    const double extent = (upper - lower).maxCoeff();
    grid.lower = lower;
    grid.cells_per_metre = extent > 0.0 ? 2097151.0 / extent : 0.0;
  }
  // Bodies in Morton order, cut into blocks of equal contact-end counts: a body's block is
  // floor(ends before it x blocks / all ends), so blocks are contiguous key ranges.
  std::vector<std::pair<std::uint64_t, std::size_t>> sorted;
  sorted.reserve(bodies.size());
  std::size_t total_ends = 0;
  for (const std::size_t body : bodies) {
    sorted.emplace_back(grid.key(state.position[body]), body);
    total_ends += block_of[body];
  }
  std::sort(sorted.begin(), sorted.end());
  SweepPlan plan;
  plan.body_order.reserve(sorted.size());
  for (const auto& [key, body] : sorted) plan.body_order.push_back(body);
  std::size_t ends_before = 0;
  for (const auto& [key, body] : sorted) {
    const std::size_t ends = block_of[body];
    block_of[body] = ends_before * blocks / total_ends;
    ends_before += ends;
  }
  // The tree over the blocks; groups are its nodes ordered by (height, first block).
  std::vector<BlockNode> nodes;
  build_block_tree(nodes, 0, blocks);
  std::vector<std::size_t> by_phase(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) by_phase[i] = i;
  std::sort(by_phase.begin(), by_phase.end(), [&](std::size_t x, std::size_t y) {
    return std::pair(nodes[x].height, nodes[x].first) < std::pair(nodes[y].height, nodes[y].first);
  });
  std::vector<std::size_t> group_of_node(nodes.size());
  for (std::size_t g = 0; g < by_phase.size(); ++g) group_of_node[by_phase[g]] = g;
  // Each contact goes to the lowest node holding all its moving bodies (the root if none moves);
  // within a group the contacts follow the Morton keys of their points (ties by index).
  const auto n = static_cast<std::ptrdiff_t>(contacts.size());
  const bool parallel = n >= min_parallel_items;
  std::vector<std::size_t> group_of(contacts.size());
  std::vector<std::uint64_t> point_key(contacts.size());
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const std::size_t a = contacts[k].id.body_a, b = contacts[k].id.body_b;
    const bool a_moves = !model.is_fixed(a), b_moves = !model.is_fixed(b);
    std::size_t node = 0;
    if (a_moves || b_moves) {
      const std::size_t block_a = a_moves ? block_of[a] : block_of[b];
      const std::size_t block_b = b_moves ? block_of[b] : block_of[a];
      node = common_node(nodes, std::min(block_a, block_b), std::max(block_a, block_b));
    }
    group_of[k] = group_of_node[node];
    point_key[k] = grid.key(contacts[k].point);
  }
  // A counting sort by group, then each group sorted on its own (concurrently).
  plan.group_start.assign(nodes.size() + 1, 0);
  for (const std::size_t g : group_of) ++plan.group_start[g + 1];
  for (std::size_t g = 0; g < nodes.size(); ++g) plan.group_start[g + 1] += plan.group_start[g];
  plan.order.resize(contacts.size());
  std::vector<std::size_t> cursor(plan.group_start.begin(), plan.group_start.end() - 1);
  for (std::size_t k = 0; k < contacts.size(); ++k) plan.order[cursor[group_of[k]]++] = k;
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
  for (std::ptrdiff_t g = 0; g < static_cast<std::ptrdiff_t>(nodes.size()); ++g) {
    const auto first = plan.order.begin() + static_cast<std::ptrdiff_t>(plan.group_start[static_cast<std::size_t>(g)]);
    const auto last = plan.order.begin() + static_cast<std::ptrdiff_t>(plan.group_start[static_cast<std::size_t>(g) + 1]);
    std::sort(first, last, [&](std::size_t x, std::size_t y) { return std::pair(point_key[x], x) < std::pair(point_key[y], y); });
  }
  plan.phase_start.push_back(0);
  for (std::size_t g = 1; g < nodes.size(); ++g) {
    if (nodes[by_phase[g]].height != nodes[by_phase[g - 1]].height) plan.phase_start.push_back(g);
  }
  plan.phase_start.push_back(nodes.size());
  plan.parent_group.assign(nodes.size(), nodes.size());
  for (const BlockNode& node : nodes) {
    if (node.last - node.first == 1) continue;
    const std::size_t self = group_of_node[static_cast<std::size_t>(&node - nodes.data())];
    plan.parent_group[group_of_node[node.left]] = self;
    plan.parent_group[group_of_node[node.right]] = self;
  }
  return plan;
}

SolverStats solve_contacts(const Model& model, const State& state, const SolverOptions& options,
                           ContactList& contacts, BodyVelocities& velocity) {
  SolverStats stats;
  const auto start = Clock::now();
  // Only a polish works on the ContactList and needs the world inverse inertias as an array (the
  // compact copy computes its own): when none can run, they are not made (72 bytes a body).
  // Nor with rolling or twisting resistance: the polish knows the forces' law only.
  const bool may_polish = options.polish_after > 0 && contacts.size() <= options.polish_max_contacts &&
                          options.polish_attempts_per_step > 0 && !model.contact_laws.any_resists_rotation();
  const std::vector<Mat3> inverse_inertia = may_polish ? world_inverse_inertias(model, state) : std::vector<Mat3>();
  BodyCoupledProblem problem{model, contacts, velocity, inverse_inertia};

  const SweepPlan plan = plan_sweep(model, state, contacts, options.block_count);
  const std::size_t groups = plan.group_start.size() - 1;
  // Small problems, or one thread: the same order without an OpenMP team (even a one-thread team
  // costs a futex round trip per sweep).
  bool parallel = static_cast<std::ptrdiff_t>(contacts.size()) >= min_parallel_items && groups > 1 &&
                  omp_get_max_threads() > 1;
  // The sweeps work on a compact copy in the plan's order (contact p of the copy = plan.order[p]);
  // its velocities are the free velocities and its impulses last step's, not yet applied.
  CompactProblem compact = gather_problem(model, state, plan, contacts, velocity, parallel);
  std::vector<double> group_sum(groups, 0.0);
  auto group_points = [&](std::size_t g) { return std::pair(plan.group_start[g], plan.group_start[g + 1]); };

  // The scale of the residual (nlgs_solver/README.md, "Convergence criterion"):
  // sqrt(||q_closing||^2 + ||W_nn r||^2), q_closing the local velocities with no contact impulse
  // (free velocity minus target) of the contacts the free motion drives together (q_n < 0), and
  // W_nn r the velocity changes the impulses make. Open contacts of falling grains have q_n of the
  // order gap / h: counting them (the earlier ||q||) let a deposit whose few loaded contacts were
  // far from converged pass the test. Summed group by group, then in group order (the same sum for
  // any thread count); if no contact closes, ||q|| of all of them.
  std::vector<double> group_all(groups, 0.0);
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(groups); ++i) {
    const auto [first, last] = group_points(static_cast<std::size_t>(i));
    double closing = 0.0, all = 0.0;
    for (std::size_t p = first; p < last; ++p) {
      const Vec3 q = compact.local_velocity(p);
      all += q.squaredNorm();
      if (q.x() < 0.0) closing += q.squaredNorm();
    }
    group_sum[static_cast<std::size_t>(i)] = closing;
    group_all[static_cast<std::size_t>(i)] = all;
  }
  double free_norm_squared = 0.0, all_norm_squared = 0.0;
  for (std::size_t g = 0; g < groups; ++g) {
    free_norm_squared += group_sum[g];
    all_norm_squared += group_all[g];
  }
  if (free_norm_squared == 0.0) free_norm_squared = all_norm_squared;
  // Warm start: the velocities must include the starting impulses (inside the cone), applied in
  // the sweeps' order and concurrency (visit_groups).
  // Cohesion (ContactLaw::cohesion): the sweeps solve for the shifted impulse r~ = r + c e_n in
  // the plain Signorini-Coulomb cone, the constant -c e_n being part of the free motion; the
  // contacts hold r~ until the end of the solve (the polish works on the same shifted problem).
  const bool cohesive = model.contact_laws.any_cohesive();
  visit_groups(plan, parallel, [&](std::size_t g) {
    const auto [first, last] = group_points(g);
    for (std::size_t p = first; p < last; ++p) {
      CompactProblem::Point& point = compact.points[p];
      const double cohesive_impulse = cohesive ? contacts[plan.order[p]].cohesive_impulse : 0.0;
      Vec3& r = point.impulse;
      r.x() += cohesive_impulse;
      r = project_onto_coulomb_cone(r, point.friction_coefficient);
      const Vec3 applied(r.x() - cohesive_impulse, r.y(), r.z());
      if (applied != Vec3::Zero()) compact.apply_impulse_change(p, applied);
    }
  });

  std::vector<SweepResult> group_result;
  std::vector<double> group_seconds;
  std::vector<std::size_t> positions(contacts.size());
  for (std::size_t p = 0; p < positions.size(); ++p) positions[p] = p;
  int next_polish = options.polish_after;
  if (!contacts.empty()) {
    for (stats.iterations = 1; stats.iterations <= options.max_iterations; ++stats.iterations) {
      const auto sweep_start = Clock::now();
      RotatingProblem rotating{compact};
      const SweepResult sweep =
          compact.rotation.empty()
              ? planned_sweep(compact, plan, positions, options.relaxation, parallel, group_result, group_seconds)
              : planned_sweep(rotating, plan, positions, options.relaxation, parallel, group_result, group_seconds);
      if (parallel) {
        // When the threaded sweep took longer than its work on one thread, the threads waited for
        // cores busy with other processes: sweep serially for the rest of the step. Both paths
        // give the same iterate to the bit, so this timing-based choice cannot change the result.
        double work = 0.0;
        for (const double t : group_seconds) work += t;
        if (std::chrono::duration<double>(Clock::now() - sweep_start).count() > work) parallel = false;
      }
      if (std::sqrt(sweep.residual_squared) <= options.tolerance * std::sqrt(free_norm_squared + sweep.impulse_squared)) {
        stats.converged = true;
        break;
      }
      if (may_polish && stats.iterations == next_polish && stats.polish_attempts < options.polish_attempts_per_step) {
        ++stats.polish_attempts;
        bool polished = false;
        scatter_problem(model, plan, compact, contacts, velocity, parallel);
        // The polish measures ||F|| / ||q|| over every contact: the same test, rescaled.
        const double tolerance = all_norm_squared > 0.0
                                     ? options.tolerance * std::sqrt((free_norm_squared + sweep.impulse_squared) / all_norm_squared)
                                     : options.tolerance;
        stats.newton_iterations += polish_contacts(model, problem, options, tolerance, polished);
        refresh_problem(plan, contacts, velocity, compact);
        next_polish *= 2;
        if (polished) {
          stats.converged = true;
          break;
        }
      }
    }
    stats.iterations = std::min(stats.iterations, options.max_iterations);
    scatter_problem(model, plan, compact, contacts, velocity, parallel);
  } else {
    stats.converged = true;
  }

  // Final residual on the end-of-step velocities (one pass, no local solves), and statuses; on the
  // compact copy (the same numbers as the contacts' after the scatter), group by group.
  std::vector<std::size_t> group_active(groups, 0);
  std::fill(group_sum.begin(), group_sum.end(), 0.0);
  std::fill(group_all.begin(), group_all.end(), 0.0);
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(groups); ++i) {
    const auto g = static_cast<std::size_t>(i);
    const auto [first, last] = group_points(g);
    for (std::size_t p = first; p < last; ++p) {
      const CompactProblem::Point& point = compact.points[p];
      const Vec3& r = point.impulse;
      group_sum[g] += natural_map(r, compact.local_velocity(p), point.friction_coefficient, point.delassus(0, 0)).squaredNorm();
      group_all[g] += (point.delassus(0, 0) * r).squaredNorm();
      const auto [spin_residual, spin_impulse] = compact.rotation_residual(p);
      group_sum[g] += spin_residual;
      group_all[g] += spin_impulse;
      if (r.x() > 0.0) ++group_active[g];
      contacts[plan.order[p]].status = r.x() <= 0.0 ? ContactStatus::open
                                       : tangential_norm(r) >= point.friction_coefficient * r.x() * (1.0 - 1e-9)
                                           ? ContactStatus::sliding
                                           : ContactStatus::sticking;
    }
  }
  double residual_squared = 0.0, impulse_squared = 0.0;
  for (std::size_t g = 0; g < groups; ++g) {
    residual_squared += group_sum[g];
    impulse_squared += group_all[g];
    stats.active_contacts += group_active[g];
  }
  const double scale_squared = free_norm_squared + impulse_squared;
  stats.residual = scale_squared > 0.0 ? std::sqrt(residual_squared / scale_squared) : std::sqrt(residual_squared);
  if (cohesive) {
    for (Contact& c : contacts) c.impulse.x() -= c.cohesive_impulse;  // back from r~ to r
  }
  stats.sweep_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return stats;
}

}  // namespace rubble
