#include "simulation/run_support.hpp"

#include <cmath>
#include <fmt/format.h>
#include <stdexcept>

#include "core/integrator.hpp"

namespace rubble::run_support {
namespace {

/// What is wrong with one body's velocity (non-finite, or faster than `limit` if limit >= 0).
std::optional<std::string> velocity_problem(const Vec3& v, const Vec3& w, double limit) {
  if (!v.allFinite() || !w.allFinite()) {
    return fmt::format("non-finite velocity ({}, {}, {}) m/s, angular ({}, {}, {}) rad/s", v.x(), v.y(), v.z(), w.x(),
                       w.y(), w.z());
  }
  if (limit >= 0.0 && v.norm() > limit) {
    // stableNorm: |v| of a finite v can overflow the plain norm (1e300 m/s reads "inf").
    return fmt::format("runaway speed {:.4g} m/s above the bound {:.4g} m/s", v.stableNorm(), limit);
  }
  return std::nullopt;
}

}  // namespace

std::string format_duration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const long long s = std::llround(seconds);
  if (s >= 3600) return fmt::format("{}h{:02}m", s / 3600, (s % 3600) / 60);
  if (s >= 60) return fmt::format("{}m{:02}s", s / 60, s % 60);
  return fmt::format("{}s", s);
}

/// The runaway bound on body b's speed (m/s), or a negative number when there is none.
double speed_limit(const Model& model, std::size_t b, double h, double max_speed) {
  if (max_speed != 0.0) return max_speed;  // explicit bound, or < 0: disabled
  // A grain that moves farther than its bounding radius in one step can pass through a
  // neighbour or a wall between two detections: the contact law is no longer enforced.
  return model.bounding_radius[b] / h;
}

/// The first body (lowest id) whose end-of-step state is non-finite or runs away. Cheap: one
/// pass over the bodies per step.
std::optional<Problem> check_state(const Model& model, const State& state, double h, double max_speed) {
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!state.position[b].allFinite() || !state.orientation[b].coeffs().allFinite()) {
      return Problem{b, fmt::format("non-finite position ({}, {}, {}) or orientation", state.position[b].x(),
                                    state.position[b].y(), state.position[b].z())};
    }
    const double limit = model.is_fixed(b) ? -1.0 : speed_limit(model, b, h, max_speed);
    if (auto what = velocity_problem(state.velocity[b], state.angular_velocity[b], limit)) return Problem{b, *what};
  }
  return std::nullopt;
}

/// After a failed step, finds the first stage whose output was bad, reading the stages' outputs
/// left in the workspace (forces, contacts, impulses, end-of-step velocities) in step order and
/// recomputing the one that is overwritten (the free velocity, from the state before the step).
/// Only runs on failure, so the run pays nothing for it.
std::string locate_failure(const Model& model, const State& before, const StepWorkspace& workspace,
                           const StepOptions& options, double max_speed, Problem& problem) {
  const double h = options.integrator.time_step;
  const std::size_t n = model.body_count();
  for (std::size_t b = 0; b < n && b < workspace.force.size(); ++b) {
    if (!workspace.force[b].allFinite()) {
      problem = {b, "non-finite external force"};
      return "external_forces";
    }
  }
  BodyVelocities free;
  State midpoint = before;
  drift_to_midpoint(model, options.integrator, midpoint);
  compute_free_velocity(model, midpoint, workspace.force, {}, options.integrator, free);
  for (std::size_t b = 0; b < n; ++b) {
    if (model.is_fixed(b)) continue;
    if (auto what = velocity_problem(free.linear[b], free.angular[b], speed_limit(model, b, h, max_speed))) {
      problem = {b, "free velocity: " + *what};
      return "free_velocity";
    }
  }
  const auto contact_body = [](const Contact& c) { return static_cast<std::size_t>(c.id.body_b); };
  for (const Contact& c : workspace.carry.contacts) {
    if (!c.point.allFinite() || !c.frame.allFinite() || !std::isfinite(c.gap)) {
      problem = {contact_body(c), fmt::format("contact with body {}: non-finite point, frame or gap", c.id.body_a)};
      return "narrow_phase";
    }
  }
  for (const Contact& c : workspace.carry.contacts) {
    if (!c.delassus.allFinite() || !std::isfinite(c.normal_velocity_target) ||
        !std::isfinite(c.normal_velocity_before)) {
      problem = {contact_body(c),
                 fmt::format("contact with body {}: non-finite Delassus block or target velocity", c.id.body_a)};
      return "solver_preparation";
    }
  }
  for (const Contact& c : workspace.carry.contacts) {
    if (!c.impulse.allFinite()) {
      problem = {contact_body(c), fmt::format("contact with body {}: non-finite impulse", c.id.body_a)};
      return "nlgs_sweeps";
    }
  }
  for (std::size_t b = 0; b < n && b < workspace.velocity.linear.size(); ++b) {
    if (model.is_fixed(b)) continue;
    if (auto what = velocity_problem(workspace.velocity.linear[b], workspace.velocity.angular[b],
                                     speed_limit(model, b, h, max_speed))) {
      problem = {b, "end-of-step velocity: " + *what};
      return "nlgs_sweeps";
    }
  }
  return "finish_step";
}

/// Grains whose mass properties overflowed or vanished (e.g. a radius of 1e200 m gives an
/// infinite mass, which the solver would take for a wall's zero inverse mass) cannot be run:
/// reported as bad input before anything is written.
void check_mass_properties(const Model& model) {
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_grain(b)) continue;
    // A driven grain has zero inverse mass and inertia by design (drive_body, core/model.hpp): only
    // its size can be out of range.
    const bool mass_ok =
        model.is_driven(b) || (std::isfinite(model.mass[b]) && model.mass[b] > 0.0 && model.inverse_mass[b] > 0.0 &&
                               std::isfinite(model.inverse_mass[b]) && model.principal_inertia[b].allFinite() &&
                               (model.principal_inertia[b].array() > 0.0).all());
    const bool ok = mass_ok && std::isfinite(model.bounding_radius[b]);
    if (!ok) {
      throw std::invalid_argument(fmt::format(
          "body {} (a grain): mass {} kg, principal inertia ({}, {}, {}) kg m^2, bounding radius {} m: expected "
          "finite positive values (is its size or density out of range?)",
          b, model.mass[b], model.principal_inertia[b].x(), model.principal_inertia[b].y(),
          model.principal_inertia[b].z(), model.bounding_radius[b]));
    }
  }
}

/// The system's reason in an I/O error: HDF5 buries it in "..., error message = 'No space left
/// on device', ..." after a time stamp and buffer addresses; the file and operation come first.
std::string short_reason(const std::string& what) {
  const std::string marker = "error message = '";
  const auto at = what.find(marker);
  if (at == std::string::npos) return what;
  const auto end = what.find('\'', at + marker.size());
  const std::string reason =
      what.substr(at + marker.size(), end == std::string::npos ? std::string::npos : end - at - marker.size());
  const auto stamp = what.find(": time = ");
  return (stamp == std::string::npos ? std::string() : what.substr(0, stamp) + ": ") + reason;
}

/// The rest watcher's state for the progress line: each measured value against its threshold,
/// "rest p99 1.2e-03/2.6e-03 m/s  dZ 0.004/0.02  dC 1.3%/5%  quiet 120/1720 s".
std::string rest_progress(const RestDetector& rest, double time) {
  const RestCriterion& c = rest.criterion;
  const std::string which = c.quantile >= 1.0 ? std::string("max") : fmt::format("p{:.4g}", 100.0 * c.quantile);
  return fmt::format("rest {} {:.2e}/{:.2e} m/s  dZ {:.3f}/{:.3g}  dC {:.1f}%/{:.3g}%  quiet {:.4g}/{:.4g} s", which,
                     rest.last_speed, c.speed, rest.last_coordination_change, c.coordination_change,
                     100.0 * rest.last_contact_change, 100.0 * c.contact_change,
                     rest.window_start ? time - *rest.window_start : 0.0, c.duration);
}

/// The sentence for a run stopped at rest: what held, measured against what.
std::string rest_reason(const RestDetector& rest, double time) {
  const RestCriterion& c = rest.criterion;
  const std::string which = c.quantile >= 1.0 ? std::string("max") : fmt::format("p{:.4g}", 100.0 * c.quantile);
  return fmt::format(
      "at rest at t = {:.6g} s: for {:.4g} s (since t = {:.6g} s) {}(|v| + |w| r) stayed below {:.3g} m/s (now "
      "{:.3g}), Z moved by at most {:.3g} (now {:.3g}) and at most {:.3g}% of the contacts changed (now {:.3g}%)",
      time, c.duration, rest.window_start.value_or(time), which, c.speed, rest.last_speed, c.coordination_change,
      rest.last_coordination_change, 100.0 * c.contact_change, 100.0 * rest.last_contact_change);
}

}  // namespace rubble::run_support
