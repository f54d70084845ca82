#include "nlgs_solver/nlgs.hpp"

#include <chrono>
#include <cmath>
#include <algorithm>
#include <numeric>
#include <span>

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
    // Walls are never written: contacts of one colour may share a wall and run in parallel.
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

/// Normal velocity target b of the unilateral condition 0 <= r_n _|_ U_n - b >= 0.
/// - Open contact (the free motion keeps the gap open at the end of the step): b is the velocity
///   that would just close the gap, g + h((1 - theta) U_n^- + theta U_n) = 0, so a contact pushed
///   by others still cannot cross it.
/// - Closing or closed contact (LMGC90's predicted-gap activation, g_pred <= 0): Newton's impact
///   law U_n >= -e_n U_n^- (seed 001 sec. 2.1), plus, when already interpenetrated, a separation
///   velocity removing a fraction of the overlap per step (capped).
double normal_velocity_target(const Contact& c, double free_normal_velocity, const IntegratorOptions& integrator,
                              const SolverOptions& options) {
  const double h = integrator.time_step;
  const double theta = integrator.theta;
  const double before = c.normal_velocity_before;
  const double predicted_gap = c.gap + h * ((1.0 - theta) * before + theta * free_normal_velocity);
  if (predicted_gap > 0.0) return -(c.gap + h * (1.0 - theta) * before) / (h * theta);
  double target = c.normal_restitution * std::max(-before, 0.0);
  if (c.gap < 0.0 && options.penetration_correction > 0.0) {
    target = std::max(target, std::min(options.penetration_correction * (-c.gap) / h, options.max_correction_velocity));
  }
  return target;
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

/// Contacts grouped by colour: no two contacts of one colour share a moving body, so a colour's
/// local solves are independent and can run on any number of threads with the same result.
/// Greedy colouring in contact order (deterministic); colours are swept in increasing order.
struct ContactColouring {
  std::vector<std::size_t> order;         ///< contact indices, colour by colour
  std::vector<std::size_t> colour_start;  ///< colours + 1 offsets into order
};

ContactColouring colour_contacts(const Model& model, const ContactList& contacts) {
  std::vector<std::vector<std::uint64_t>> used(model.body_count());  // colour bitsets per body
  std::vector<std::size_t> colour(contacts.size());
  std::size_t colour_count = 0;
  auto is_used = [&](std::size_t body, std::size_t c) {
    return !model.is_fixed(body) && c / 64 < used[body].size() && (used[body][c / 64] >> (c % 64)) & 1u;
  };
  auto mark = [&](std::size_t body, std::size_t c) {
    if (model.is_fixed(body)) return;
    if (used[body].size() <= c / 64) used[body].resize(c / 64 + 1, 0);
    used[body][c / 64] |= std::uint64_t{1} << (c % 64);
  };
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    const std::size_t a = contacts[k].id.body_a, b = contacts[k].id.body_b;
    std::size_t c = 0;
    while (is_used(a, c) || is_used(b, c)) ++c;
    mark(a, c);
    mark(b, c);
    colour[k] = c;
    colour_count = std::max(colour_count, c + 1);
  }
  ContactColouring result;
  result.colour_start.assign(colour_count + 1, 0);
  for (const std::size_t c : colour) ++result.colour_start[c + 1];
  for (std::size_t c = 0; c < colour_count; ++c) result.colour_start[c + 1] += result.colour_start[c];
  result.order.resize(contacts.size());
  std::vector<std::size_t> next(result.colour_start.begin(), result.colour_start.end() - 1);
  for (std::size_t k = 0; k < contacts.size(); ++k) result.order[next[colour[k]]++] = k;
  return result;
}

/// One sweep over all colours. Each colour is cut into fixed-size chunks whose residual sums are
/// added in chunk order, so the sum (and the stopping decision) is the same for any thread count.
double coloured_sweep(BodyCoupledProblem& problem, const ContactColouring& colouring, double relaxation,
                      std::vector<double>& chunk_residual) {
  constexpr std::size_t chunk = 128;
  double residual_squared = 0.0;
  for (std::size_t c = 0; c + 1 < colouring.colour_start.size(); ++c) {
    const std::size_t begin = colouring.colour_start[c];
    const std::size_t end = colouring.colour_start[c + 1];
    const auto chunks = static_cast<std::ptrdiff_t>((end - begin + chunk - 1) / chunk);
    chunk_residual.assign(static_cast<std::size_t>(chunks), 0.0);
    auto sweep_chunk = [&](std::ptrdiff_t i) {
      const std::size_t first = begin + static_cast<std::size_t>(i) * chunk;
      const std::size_t last = std::min(end, first + chunk);
      const std::span<const std::size_t> part(colouring.order.data() + first, last - first);
      chunk_residual[static_cast<std::size_t>(i)] = nlgs_sweep(problem, part, relaxation).residual_squared;
    };
    if (static_cast<std::ptrdiff_t>(end - begin) >= min_parallel_items) {
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t i = 0; i < chunks; ++i) sweep_chunk(i);
    } else {
      // Small colours: no OpenMP team at all (even a one-thread team costs a futex round trip).
      for (std::ptrdiff_t i = 0; i < chunks; ++i) sweep_chunk(i);
    }
    for (const double r : chunk_residual) residual_squared += r;
  }
  return residual_squared;
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
int polish_contacts(const Model& model, BodyCoupledProblem& coupled, const SolverOptions& options, bool& converged) {
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
  polish.tolerance = options.tolerance;
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
  converged = error <= options.tolerance;
  return steps;
}

}  // namespace

void prepare_contacts(const Model& model, const State& state, const BodyVelocities& free_velocity,
                      const IntegratorOptions& integrator, const SolverOptions& options, ContactList& contacts) {
  const std::vector<Mat3> inverse_inertia = world_inverse_inertias(model, state);
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(contacts.size());
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
    c.normal_velocity_target = normal_velocity_target(c, free_normal, integrator, options);
    if (!options.warm_start) c.impulse = Vec3::Zero();
  }
}

SolverStats solve_contacts(const Model& model, const State& state, const SolverOptions& options,
                           ContactList& contacts, BodyVelocities& velocity) {
  SolverStats stats;
  const auto start = Clock::now();
  const std::vector<Mat3> inverse_inertia = world_inverse_inertias(model, state);
  BodyCoupledProblem problem{model, contacts, velocity, inverse_inertia};

  // ||q||: the local velocities with no contact impulse (free velocity minus target).
  double free_norm_squared = 0.0;
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    free_norm_squared += problem.local_velocity(k).squaredNorm();
  }
  // Warm start: the velocities must include the starting impulses.
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    Vec3& r = contacts[k].impulse;
    r = project_onto_coulomb_cone(r, contacts[k].friction_coefficient);
    if (r != Vec3::Zero()) problem.apply_impulse_change(k, r);
  }
  const double q_norm = std::sqrt(free_norm_squared);
  const double scale = q_norm > 0.0 ? 1.0 / q_norm : 1.0;

  const ContactColouring colouring = colour_contacts(model, contacts);
  std::vector<double> chunk_residual;
  int next_polish = options.polish_after;
  if (!contacts.empty()) {
    for (stats.iterations = 1; stats.iterations <= options.max_iterations; ++stats.iterations) {
      const double sweep_residual_squared = coloured_sweep(problem, colouring, options.relaxation, chunk_residual);
      if (std::sqrt(sweep_residual_squared) * scale <= options.tolerance) {
        stats.converged = true;
        break;
      }
      if (options.polish_after > 0 && stats.iterations == next_polish && contacts.size() <= options.polish_max_contacts &&
          stats.polish_attempts < options.polish_attempts_per_step) {
        ++stats.polish_attempts;
        bool polished = false;
        stats.newton_iterations += polish_contacts(model, problem, options, polished);
        next_polish *= 2;
        if (polished) {
          stats.converged = true;
          break;
        }
      }
    }
    stats.iterations = std::min(stats.iterations, options.max_iterations);
  } else {
    stats.converged = true;
  }

  // Final residual on the end-of-step velocities (one pass, no local solves), and statuses.
  double residual_squared = 0.0;
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    Contact& c = contacts[k];
    residual_squared += natural_map(c.impulse, problem.local_velocity(k), c.friction_coefficient, c.delassus(0, 0))
                            .squaredNorm();
    const double tangential = tangential_norm(c.impulse);
    if (c.impulse.x() > 0.0) ++stats.active_contacts;
    c.status = c.impulse.x() <= 0.0 ? ContactStatus::open
               : tangential >= c.friction_coefficient * c.impulse.x() * (1.0 - 1e-9) ? ContactStatus::sliding
                                                                                     : ContactStatus::sticking;
  }
  stats.residual = std::sqrt(residual_squared) * scale;
  stats.sweep_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return stats;
}

}  // namespace rubble
