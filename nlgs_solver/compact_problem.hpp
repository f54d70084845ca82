#pragma once
// The sweeps' compact copy of a step's contact problem (nlgs_solver/README.md, "Sweep order and
// threads", Cache): the contacts in the plan's order and their bodies in Morton order, gathered
// from the ContactList and the body velocities once per step and scattered back after the solve.
// Everything in solve_contacts after the gather (warm start, sweeps, polish, residuals) works on
// it. W = H^T M^-1 H is never assembled: u_k is read off the two bodies' current velocities and an
// impulse change is applied to them at once (Jean 1999).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "nlgs_solver/nlgs.hpp"
#include "nlgs_solver/coulomb.hpp"
#include "nlgs_solver/sweep.hpp"

namespace rubble {

/// The levers of a contact point on one body, [arm x f_0, arm x f_1, arm x f_2] (f_i the frame's
/// columns): arm x (frame delta) = levers delta, the torque of a local impulse change delta.
inline Mat3 levers(const Vec3& arm, const Mat3& frame) {
  Mat3 lever;
  for (int i = 0; i < 3; ++i) lever.col(i) = arm.cross(frame.col(i));
  return lever;
}

/// frame^T (v_b + w_b x arm_b - v_a - w_a x arm_a), the relative velocity of a contact point in its
/// frame, evaluated as u_i = f_i . (v_b - v_a) + w_b . (arm_b x f_i) - w_a . (arm_a x f_i) (the
/// triple product is cyclic): the levers do not depend on the velocities, so a sweep's chain from
/// the velocities the point before wrote to this u is one product and a short sum
/// (bench/RESULTS.md, "The sweep's chain shortened").
inline Vec3 relative_local_velocity(const Mat3& frame, const Vec3& arm_a, const Vec3& arm_b, const Vec3& linear_a,
                                    const Vec3& angular_a, const Vec3& linear_b, const Vec3& angular_b) {
  const Vec3 linear = linear_b - linear_a;
  Vec3 u;
  for (int i = 0; i < 3; ++i) {
    const Vec3 f = frame.col(i);
    u(i) = f.dot(linear) + (arm_b.cross(f).dot(angular_b) - arm_a.cross(f).dot(angular_a));
  }
  return u;
}

/// The contact problem in the plan's order (point p is contact plan.order[p]; bodies in Morton
/// order, then the walls): a sweep reads its contacts one after the other in memory and the
/// velocities of bodies near in space from nearby memory, instead of hopping through the
/// ContactList (sorted by body id) and the body arrays (numbered as the generator placed the
/// grains). Provides the Problem interface of nlgs_sweep (sweep.hpp).
struct CompactProblem {
  /// One contact point: what a sweep reads and writes of it.
  struct Point {
    Mat3 frame;                     ///< contact frame (normal, t, s) as columns, world
    Mat3 delassus;                  ///< W_kk in the contact frame
    Mat3 delassus_inverse;          ///< W_kk^-1, for the local solver's sticking test
    Vec3 arm_a, arm_b;              ///< contact point minus each body's centre, world
    Vec3 impulse;                   ///< r_k in the contact frame
    double friction_coefficient;    ///< mu
    double normal_velocity_target;  ///< b, folded into the local velocity
    std::uint32_t a, b;             ///< local body indices (into `bodies`)
  };
  /// One body: its current velocity and what an impulse does to it.
  struct Body {
    Vec3 linear, angular;  ///< current velocity (free velocity plus the impulses applied so far)
    Mat3 inverse_inertia;  ///< world inverse inertia at the start of the step
    double inverse_mass;   ///< 0 for a wall (Model::is_fixed)
  };
  /// Rolling and twisting resistance of a sphere contact (ContactLaw::rolling_friction,
  /// twisting_friction): the contact's angular block, solved after its force in each sweep.
  struct Rotation {
    double compliance;   ///< a: relative angular velocity per unit angular impulse (isotropic for spheres), 1/(kg m^2)
    double twist_bound;  ///< mu_t r_eff, m: bound on the twisting impulse per unit normal impulse
    double roll_bound;   ///< mu_r r_eff, m: bound on the rolling impulse per unit normal impulse
    double radius;       ///< r_eff, m: turns the block's residual into velocity units
    Vec3 impulse;        ///< (twist about n, roll about t, roll about s), N m s; last step's at the start (warm start)
  };
  /// How far a body's contact-point velocities may have moved during the solve: the sums of the
  /// 1-norms of every linear and angular velocity change applied to it (nlgs_solver/README.md,
  /// "Open contacts skipped"). Walls stay at zero.
  struct Drift {
    double linear = 0.0;   ///< sum of ||delta v||_1, m/s
    double angular = 0.0;  ///< sum of ||delta omega||_1, rad/s
  };
  /// What a sweep last saw of a point that it left open (r = 0, u_n > 0): while the bodies'
  /// drift since then stays below `slack`, u_n is still positive, the local solver would return
  /// r = 0 again and the point's residual is 0, so the sweep may pass it by. Floats rounded
  /// towards the safe side (slack and snapshot down, arms up): 16 bytes a point.
  struct OpenWatch {
    float slack = -std::numeric_limits<float>::infinity();  ///< u_n then, less its rounding error; -inf: not watched
    float snapshot = 0.0F;                                  ///< the point's drift bound then (drift_bound)
    float arm_a = 0.0F;                                     ///< ||arm_a||_2, m
    float arm_b = 0.0F;                                     ///< ||arm_b||_2, m
  };
  /// rotation_of_point's value for a point without a rotation block.
  static constexpr std::uint32_t no_rotation = std::numeric_limits<std::uint32_t>::max();
  std::vector<Point> points;                     ///< in the plan's order
  std::vector<Body> bodies;                      ///< moving bodies in Morton order, then walls
  std::vector<std::size_t> body_id;              ///< model index of each local body
  std::vector<std::uint32_t> rotation_of_point;  ///< per point, index into `rotation` (empty: no such law in the scene)
  std::vector<Rotation> rotation;                ///< the rotation blocks
  /// Per point, the tangential part of the target velocity, -e_t u_t- (ContactLaw::
  /// tangential_restitution; u_t- the contact point's tangential velocity at t_n), m/s; empty when
  /// no law of the scene has e_t > 0. Kept out of Point so that plain scenes' sweeps read no more.
  std::vector<Vec2> tangential_target;
  std::vector<Drift> drift;      ///< per body (same index as `bodies`)
  std::vector<OpenWatch> watch;  ///< per point

  /// Number of contact points.
  std::size_t size() const { return points.size(); }
  /// W_kk of point k.
  const Mat3& delassus(std::size_t k) const { return points[k].delassus; }
  /// W_kk^-1 of point k.
  const Mat3& delassus_inverse(std::size_t k) const { return points[k].delassus_inverse; }
  /// mu of point k.
  double friction_coefficient(std::size_t k) const { return points[k].friction_coefficient; }
  /// r_k of point k.
  Vec3& impulse(std::size_t k) { return points[k].impulse; }

  /// u = R^T (v_b + w_b x arm_b - v_a - w_a x arm_a) - b e_n: the target velocity b is folded in,
  /// so the law reads 0 <= r_n _|_ u_n >= 0 (relative_local_velocity).
  Vec3 local_velocity(std::size_t k) const {
    const Point& c = points[k];
    const Body& a = bodies[c.a];
    const Body& b = bodies[c.b];
    Vec3 u = relative_local_velocity(c.frame, c.arm_a, c.arm_b, a.linear, a.angular, b.linear, b.angular);
    u.x() -= c.normal_velocity_target;
    return u;
  }

  /// u_k with the tangential target folded in too: u - b_t (the law on u_t+ + e_t u_t-). The
  /// residuals and ExtendedProblem read this one; plain sweeps read local_velocity.
  Vec3 full_local_velocity(std::size_t k) const {
    Vec3 u = local_velocity(k);
    if (!tangential_target.empty()) {
      u.y() -= tangential_target[k].x();
      u.z() -= tangential_target[k].y();
    }
    return u;
  }

  /// ||F_k||^2, point k's natural map on the current iterate in velocity units (rho = W_nn): the
  /// sweeps' residual measure, taken once per point (end-of-step residual, the cluster polish).
  double residual_squared(std::size_t k) const {
    const Point& c = points[k];
    return natural_map(c.impulse, full_local_velocity(k), c.friction_coefficient, c.delassus(0, 0)).squaredNorm();
  }

  /// Applies the change `delta` of point k's impulse to its two bodies (v += M^-1 H delta).
  /// Walls are never written: contacts of concurrent sweep groups may share a wall.
  /// Each change is added to the bodies' drift (the 1-norms of the velocity changes). The torque
  /// arm x (R delta) is taken as levers(arm, R) delta: one product from delta, as in
  /// relative_local_velocity.
  void apply_impulse_change(std::size_t k, const Vec3& delta) {
    const Point& c = points[k];
    const Vec3 p = c.frame * delta;  // world impulse on b; -p on a
    Body& b = bodies[c.b];
    Body& a = bodies[c.a];
    if (b.inverse_mass != 0.0) {  // Model::is_fixed
      const Vec3 linear = b.inverse_mass * p;
      const Vec3 angular = b.inverse_inertia * (levers(c.arm_b, c.frame) * delta);
      b.linear += linear;
      b.angular += angular;
      add_drift(c.b, linear, angular);
    }
    if (a.inverse_mass != 0.0) {
      const Vec3 linear = a.inverse_mass * p;
      const Vec3 angular = a.inverse_inertia * (levers(c.arm_a, c.frame) * delta);
      a.linear -= linear;
      a.angular -= angular;
      add_drift(c.a, linear, angular);
    }
  }

  /// Asks the memory for point k's bytes (nlgs_sweep, a few visits ahead). A hint only: nothing
  /// is read, so it changes no result.
  void prefetch_point(std::size_t k) const { prefetch_bytes(&points[k], sizeof(Point)); }

  /// Asks the memory for the two bodies of point k and their drifts. Reads the point's body
  /// indices: call it after prefetch_point(k) has had a few visits' time.
  void prefetch_bodies(std::size_t k) const {
    const Point& c = points[k];
    prefetch_bytes(&bodies[c.a], sizeof(Body));
    prefetch_bytes(&bodies[c.b], sizeof(Body));
    __builtin_prefetch(&drift[c.a]);
    __builtin_prefetch(&drift[c.b]);
  }

  /// Prefetches every 64-byte line of [first, first + bytes) (the blocks need not be aligned).
  static void prefetch_bytes(const void* first, std::size_t bytes) {
    const char* p = static_cast<const char*>(first);
    for (std::size_t offset = 0; offset < bytes; offset += 64) __builtin_prefetch(p + offset);
    __builtin_prefetch(p + bytes - 1);
  }

  /// Adds a velocity change of body j to its drift.
  void add_drift(std::uint32_t j, const Vec3& linear, const Vec3& angular) {
    drift[j].linear += linear.lpNorm<1>();
    drift[j].angular += angular.lpNorm<1>();
  }

  /// The bound on how much point k's normal velocity can have changed since the bodies' drift was
  /// zero: |n . (dv_b + dw_b x arm_b - dv_a - dw_a x arm_a)| <= the drifts, weighted by the arms.
  double drift_bound(std::size_t k, const OpenWatch& w) const {
    const Point& c = points[k];
    return drift[c.a].linear + static_cast<double>(w.arm_a) * drift[c.a].angular + drift[c.b].linear +
           static_cast<double>(w.arm_b) * drift[c.b].angular;
  }

  /// Whether point k is still open for sure since a sweep left it open (OpenWatch): its normal
  /// velocity then, less every change the bodies' velocities have had since, is positive. The
  /// margin 1e-9 of the drift covers the rounding of the drift sums (each addition errs by at most
  /// 1.1e-16 of the sum, and a body gets far fewer than 10^6 updates in a step).
  bool stays_open(std::size_t k) const {
    const OpenWatch& w = watch[k];
    if (!(w.slack > 0.0F)) return false;
    const double bound = drift_bound(k, w);
    return static_cast<double>(w.slack) > bound - static_cast<double>(w.snapshot) + 1e-9 * bound;
  }

  /// After a sweep's visit of point k (u its local velocity before the update, free_velocity =
  /// u - W_kk r_old the one without its impulse, which it has after an update to r = 0; next its
  /// impulse after): watch it if it was left open, else stop watching it.
  void note_visit(std::size_t k, const Vec3& u, const Vec3& free_velocity, const Vec3& next) {
    OpenWatch& w = watch[k];
    if (next != Vec3::Zero() || !(free_velocity.x() > 0.0)) {
      w.slack = -std::numeric_limits<float>::infinity();
      return;
    }
    const Point& c = points[k];
    const Body& a = bodies[c.a];
    const Body& b = bodies[c.b];
    const double arm_a = c.arm_a.norm(), arm_b = c.arm_b.norm();
    // The normal velocity after the update is free_velocity.x() up to rounding errors of terms of
    // these sizes (the velocities, the target, u and W r), and each later update of a velocity
    // rounds it by at most 1.1e-16 of its size: 1e-9 of them covers far more updates than a step has.
    const double size = a.linear.lpNorm<1>() + a.angular.lpNorm<1>() * arm_a + b.linear.lpNorm<1>() +
                        b.angular.lpNorm<1>() * arm_b + std::abs(c.normal_velocity_target) + u.lpNorm<1>() +
                        free_velocity.lpNorm<1>();
    w.arm_a = std::nextafter(static_cast<float>(arm_a), std::numeric_limits<float>::infinity());
    w.arm_b = std::nextafter(static_cast<float>(arm_b), std::numeric_limits<float>::infinity());
    w.slack =
        std::nextafter(static_cast<float>(free_velocity.x() - 1e-9 * size), -std::numeric_limits<float>::infinity());
    w.snapshot = std::nextafter(static_cast<float>(drift_bound(k, w)), -std::numeric_limits<float>::infinity());
  }

  /// Stops watching point k: its impulse changed outside the sweeps (a polish, the Anderson
  /// mixing), so it may no longer be an open point with r = 0.
  void forget_open_point(std::size_t k) { watch[k].slack = -std::numeric_limits<float>::infinity(); }

  /// Stops watching every point: after the impulses changed outside the sweeps (the whole polish).
  void forget_open_points() {
    for (std::size_t k = 0; k < watch.size(); ++k) forget_open_point(k);
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
    return project_onto_rotation_bounds(rotation.impulse - omega / rotation.compliance, rotation,
                                        std::max(c.impulse.x(), 0.0));
  }

  /// m projected on |m_n| <= mu_t r_eff r_n and ||(m_t, m_s)|| <= mu_r r_eff r_n (`normal` = r_n >= 0).
  static Vec3 project_onto_rotation_bounds(Vec3 m, const Rotation& rotation, double normal) {
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

  /// The sweep's rotation step of point k, right after the force's update (RotatingProblem): the
  /// block's exact solution, its residual and impulse terms added to `sums`.
  void rotation_step(std::size_t k, SweepResult& sums) {
    if (rotation_of_point[k] == no_rotation) return;
    Rotation& r = rotation[rotation_of_point[k]];
    const Vec3 next = allowed_rotation_impulse(k, r);
    const double scale = r.compliance * r.radius;
    sums.residual_squared += (scale * (r.impulse - next)).squaredNorm();
    sums.impulse_squared += (scale * next).squaredNorm();
    const Vec3 change = points[k].frame * (next - r.impulse);
    r.impulse = next;
    apply_angular_impulse_change(k, change);
  }

  /// Applies the world angular impulse `change` of point k's rotation block to its two bodies
  /// (+change on b, -change on a; walls are never written).
  void apply_angular_impulse_change(std::size_t k, const Vec3& change) {
    const Point& c = points[k];
    Body& b = bodies[c.b];
    Body& a = bodies[c.a];
    if (b.inverse_mass != 0.0) {
      const Vec3 angular = b.inverse_inertia * change;
      b.angular += angular;
      add_drift(c.b, Vec3::Zero(), angular);
    }
    if (a.inverse_mass != 0.0) {
      const Vec3 angular = a.inverse_inertia * change;
      a.angular -= angular;
      add_drift(c.a, Vec3::Zero(), angular);
    }
  }
};

/// The compact problem with the laws beyond Signorini-Coulomb-Newton: what the sweeps see when some
/// contact resists rolling or twisting (nlgs_sweep then calls resist_rotation after each force) or
/// restitutes tangentially (the tangential target in the local velocity). A separate type, so
/// that the sweeps of a scene without such laws carry no per-contact test for them.
struct ExtendedProblem {
  CompactProblem& compact;  ///< the problem itself
  /// Number of contact points.
  std::size_t size() const { return compact.size(); }
  /// W_kk of point k.
  const Mat3& delassus(std::size_t k) const { return compact.delassus(k); }
  /// W_kk^-1 of point k.
  const Mat3& delassus_inverse(std::size_t k) const { return compact.delassus_inverse(k); }
  /// mu of point k.
  double friction_coefficient(std::size_t k) const { return compact.friction_coefficient(k); }
  /// r_k of point k.
  Vec3& impulse(std::size_t k) { return compact.impulse(k); }
  /// u_k for the current impulses, tangential target included (CompactProblem::full_local_velocity).
  Vec3 local_velocity(std::size_t k) const { return compact.full_local_velocity(k); }
  /// CompactProblem::apply_impulse_change.
  void apply_impulse_change(std::size_t k, const Vec3& delta) { compact.apply_impulse_change(k, delta); }
  /// CompactProblem::rotation_step, for scenes with rotation blocks.
  void resist_rotation(std::size_t k, SweepResult& sums) {
    if (!compact.rotation.empty()) compact.rotation_step(k, sums);
  }
};

/// The compact copy of `contacts` in the plan's order, with the velocities `velocity` (the free
/// velocities at the start of the solve) and the contacts' impulses (not yet applied to the
/// velocities). Each body's world inverse inertia is computed here (the same function as the
/// preparation's, hence the same value), so no per-body array is kept beside the copy.
/// `parallel`: fill the bodies and points concurrently.
CompactProblem gather_compact_problem(const Model& model, const State& state, const SweepPlan& plan,
                                      const ContactList& contacts, const BodyVelocities& velocity, bool parallel);

/// Warm start of the rotation blocks (rolling and twisting resistance), after the forces' warm
/// start: each block's carried angular impulse, projected on its bounds for the warm-started normal
/// impulse, applied to the bodies' angular velocities. Serial, in the plan's order: the same sums
/// for any thread count. Nothing to do for a problem without rotation blocks.
void warm_start_rotations(CompactProblem& compact);

/// Copies the compact problem's impulses (and rotation blocks' angular impulses) back into
/// `contacts` and its moving bodies' velocities into `velocity` (walls are left as they are).
void scatter_compact_problem(const Model& model, const SweepPlan& plan, const CompactProblem& compact,
                             ContactList& contacts, BodyVelocities& velocity, bool parallel);

}  // namespace rubble
