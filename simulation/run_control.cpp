#include "simulation/run_control.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <limits>
#include <stdexcept>

namespace rubble {

namespace {

constexpr double infinity = std::numeric_limits<double>::infinity();

/// What scene_scales gathers over the moving grains before it knows their centre.
struct GrainTotals {
  Vec3 weighted = Vec3::Zero();  ///< sum of m x
  double volume = 0.0;
  double max_speed = 0.0;  ///< fastest grain, or fastest prescribed speed of a driven body
};

/// Counts, mass, volume, d_min and the fastest speed of the moving grains (into `scales`), and
/// the driven bodies' fastest prescribed speeds.
GrainTotals grain_totals(const Model& model, const State& state, SceneScales& scales) {
  GrainTotals totals;
  scales.min_diameter = infinity;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_grain(b) || model.is_fixed(b)) continue;
    ++scales.grains;
    scales.has_polyhedra = scales.has_polyhedra || model.shape_kind[b] == ShapeKind::polyhedron;
    scales.total_mass += model.mass[b];
    totals.weighted += model.mass[b] * state.position[b];
    totals.volume += model.volume[b];
    scales.min_diameter = std::min(scales.min_diameter, 2.0 * model.bounding_radius[b]);
    totals.max_speed = std::max(totals.max_speed, state.velocity[b].norm());
  }
  // A driven body moves grains as fast as it goes: its fastest prescribed speed at any knot (a
  // turning grain's or box's rim included; a turning plane has no rim) counts as a grain's.
  for (const std::size_t b : model.driven_bodies) {
    const PrescribedMotion& motion = model.prescribed_motions[static_cast<std::size_t>(model.motion_of_body[b])];
    const double rim = std::isfinite(model.bounding_radius[b]) ? model.bounding_radius[b] : 0.0;
    for (std::size_t k = 0; k < motion.time.size(); ++k) {
      totals.max_speed =
          std::max(totals.max_speed, motion.velocity[k].norm() + rim * motion.angular_velocity[k].norm());
    }
  }
  return totals;
}

/// The height of the grains along uniform gravity's direction (along z for other fields), m;
/// sets `scales.cloud_radius` on the way.
double grain_height(const Model& model, const State& state, const GravitySettings& gravity, const Vec3& centre,
                    SceneScales& scales) {
  double low = infinity;
  double high = -infinity;
  const Vec3 down = gravity.kind == GravitySettings::Kind::uniform && gravity.acceleration.norm() > 0.0
                        ? Vec3(gravity.acceleration.normalized())
                        : Vec3::UnitZ();
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_grain(b) || model.is_fixed(b)) continue;
    scales.cloud_radius = std::max(scales.cloud_radius, (state.position[b] - centre).norm() + model.bounding_radius[b]);
    low = std::min(low, down.dot(state.position[b]));
    high = std::max(high, down.dot(state.position[b]));
  }
  return high - low;
}

/// v_ref and T of a central field: a grain falling from rest at the cloud's farthest point r0 to
/// a grain radius from the centre (closer than that it meets other grains), in the softened
/// field: energy conservation, v = sqrt(2 G M (1/sqrt(r1^2 + eps^2) - 1/sqrt(r0^2 + eps^2))).
/// Time: the free-fall time scale sqrt(r0^3 / (G M)) (Kepler).
void central_field_scales(const Model& model, const State& state, const CentralField& c, SceneScales& scales) {
  double r0 = 0.0;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (model.is_grain(b) && !model.is_fixed(b)) r0 = std::max(r0, (state.position[b] - c.centre).norm());
  }
  const double r1 = std::min(0.5 * scales.min_diameter, r0);
  const double eps2 = c.softening * c.softening;
  const double GM = c.G * c.mass;
  scales.reference_velocity =
      std::sqrt(std::max(0.0, 2.0 * GM * (1.0 / std::sqrt(r1 * r1 + eps2) - 1.0 / std::sqrt(r0 * r0 + eps2))));
  scales.characteristic_time = GM > 0.0 ? std::sqrt((r0 * r0 * r0 + eps2 * std::sqrt(eps2)) / GM) : infinity;
}

/// v_ref and T of the scene's gravity (docs/scene-file.md, "Automatic time step"); `height` is
/// the grains' extent along uniform gravity, `max_speed` the fastest grain or driven body.
void gravity_scales(const Model& model, const State& state, const GravitySettings& gravity, double height,
                    double max_speed, SceneScales& scales) {
  switch (gravity.kind) {
    case GravitySettings::Kind::self: {
      // Escape velocity from the cloud's edge, sqrt(2GM/R): no grain falling from rest inside the
      // cloud gets faster (the potential well of a uniform sphere is 3GM/2R deep at its centre,
      // which gives only sqrt(GM/R)). Characteristic time 1/sqrt(G rho) (the LMGC90 accretion paper).
      const double G = gravity.self_gravity.G;
      scales.reference_velocity = std::sqrt(2.0 * G * scales.total_mass / scales.cloud_radius);
      scales.characteristic_time = scales.mean_density > 0.0 ? 1.0 / std::sqrt(G * scales.mean_density) : infinity;
      break;
    }
    case GravitySettings::Kind::uniform: {
      // A grain falling the height of the deposit (plus one grain) from rest: v = sqrt(2 g H),
      // in t = sqrt(2 H / g).
      const double g = gravity.acceleration.norm();
      const double fall = height + scales.min_diameter;
      scales.reference_velocity = std::max(std::sqrt(2.0 * g * fall), max_speed);
      scales.characteristic_time = g > 0.0 ? std::sqrt(2.0 * fall / g) : infinity;
      break;
    }
    case GravitySettings::Kind::central:
      central_field_scales(model, state, gravity.central, scales);
      break;
    case GravitySettings::Kind::none:
      scales.reference_velocity = max_speed;
      scales.characteristic_time = max_speed > 0.0 ? scales.min_diameter / max_speed : infinity;
      break;
  }
}

}  // namespace

SceneScales scene_scales(const Model& model, const State& state, const GravitySettings& gravity) {
  SceneScales scales;
  const GrainTotals totals = grain_totals(model, state, scales);
  if (scales.grains == 0) {
    scales.min_diameter = 0.0;
    scales.characteristic_time = infinity;
    return scales;
  }
  scales.mean_mass = scales.total_mass / static_cast<double>(scales.grains);
  scales.mean_density = totals.volume > 0.0 ? scales.total_mass / totals.volume : 0.0;
  const Vec3 centre = totals.weighted / scales.total_mass;
  const double height = grain_height(model, state, gravity, centre, scales);
  gravity_scales(model, state, gravity, height, totals.max_speed, scales);
  if (gravity.kind != GravitySettings::Kind::none) {
    scales.reference_velocity = std::max(scales.reference_velocity, totals.max_speed);
  }
  scales.rest_reference_velocity = gravity.kind == GravitySettings::Kind::uniform
                                       ? std::sqrt(gravity.acceleration.norm() * scales.min_diameter)
                                       : scales.reference_velocity;
  if (!(scales.rest_reference_velocity > 0.0)) scales.rest_reference_velocity = scales.reference_velocity;
  return scales;
}

TimeStepChoice automatic_time_step(const Model& model, const State& state, const GravitySettings& gravity) {
  TimeStepChoice choice;
  choice.scales = scene_scales(model, state, gravity);
  const SceneScales& s = choice.scales;
  const double by_travel =
      s.reference_velocity > 0.0 ? auto_step_travel_fraction * s.min_diameter / s.reference_velocity : infinity;
  const double by_time = auto_step_time_fraction * s.characteristic_time;
  if (!std::isfinite(by_travel) && !std::isfinite(by_time)) {
    throw std::invalid_argument(
        "cannot choose dt automatically: the scene has no gravity and no initial velocity, so nothing sets a time "
        "scale (give dt in s)");
  }
  if (!(std::min(by_travel, by_time) > 0.0)) {
    throw std::invalid_argument("cannot choose dt automatically: the scene's grains give a zero time step");
  }
  choice.time_step = std::min(by_travel, by_time);
  choice.rule = by_travel <= by_time ? "travel" : "time";
  return choice;
}

RestCriterion automatic_rest_criterion(const SceneScales& scales, double speed, double duration,
                                       double coordination_change) {
  RestCriterion criterion;
  criterion.coordination_change =
      coordination_change > 0.0 ? coordination_change
      : scales.grains > 0       ? auto_rest_coordination_change *
                                std::sqrt(auto_rest_coordination_grains / static_cast<double>(scales.grains))
                          : auto_rest_coordination_change;
  if (speed > 0.0) {
    criterion.speed = speed;
  } else {
    const double reference = scales.rest_reference_velocity;
    if (!(reference > 0.0) || !std::isfinite(reference)) {
      throw std::invalid_argument(
          "cannot choose rest_speed automatically: the scene has no gravity and no motion (give it in m/s)");
    }
    criterion.speed = auto_rest_speed_fraction * reference;
  }
  if (duration > 0.0) {
    criterion.duration = duration;
  } else {
    if (!std::isfinite(scales.characteristic_time)) {
      throw std::invalid_argument(
          "cannot choose rest_duration automatically: the scene has no time scale (give it in s)");
    }
    criterion.duration = auto_rest_duration_fraction * scales.characteristic_time;
  }
  return criterion;
}

RestSample rest_sample(const Model& model, const State& state, const ContactList& contacts, double quantile) {
  RestSample sample;
  sample.time = state.time;
  std::vector<double> speeds;
  speeds.reserve(model.body_count());
  std::size_t grains = 0;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_grain(b)) continue;
    ++grains;
    if (model.is_fixed(b)) continue;
    // The fastest point of the grain's bounding sphere: a grain spinning in place (33 rad/s in the
    // 200-polyhedra box deposit of issue 18) is not at rest though its centre is.
    speeds.push_back(state.velocity[b].norm() + state.angular_velocity[b].norm() * model.bounding_radius[b]);
  }
  if (!speeds.empty()) {
    // The k-th smallest speed with k = ceil(q n) - 1 (nearest rank): q = 1 is the largest.
    const double rank = std::ceil(std::clamp(quantile, 0.0, 1.0) * static_cast<double>(speeds.size())) - 1.0;
    const auto k = static_cast<std::size_t>(std::clamp(rank, 0.0, static_cast<double>(speeds.size() - 1)));
    std::nth_element(speeds.begin(), speeds.begin() + static_cast<std::ptrdiff_t>(k), speeds.end());
    sample.speed = speeds[k];
  }
  std::size_t grain_pairs = 0;
  for (const Contact& contact : contacts) {
    const double r = std::min(model.bounding_radius[contact.id.body_a], model.bounding_radius[contact.id.body_b]);
    if (!(contact.gap <= rest_contact_gap_fraction * r)) continue;
    const std::uint32_t a = std::min(contact.id.body_a, contact.id.body_b);
    const std::uint32_t b = std::max(contact.id.body_a, contact.id.body_b);
    sample.pairs.emplace_back(a, b);
  }
  std::sort(sample.pairs.begin(), sample.pairs.end());
  sample.pairs.erase(std::unique(sample.pairs.begin(), sample.pairs.end()), sample.pairs.end());
  for (const auto& [a, b] : sample.pairs) grain_pairs += model.is_grain(a) && model.is_grain(b) ? 1 : 0;
  sample.grains = grains;
  sample.coordination = grains > 0 ? 2.0 * static_cast<double>(grain_pairs) / static_cast<double>(grains) : 0.0;
  return sample;
}

double contact_change_fraction(std::span<const std::pair<std::uint32_t, std::uint32_t>> a,
                               std::span<const std::pair<std::uint32_t, std::uint32_t>> b) {
  // Both sorted: one merge pass counts the common pairs.
  std::size_t common = 0;
  auto i = a.begin();
  auto j = b.begin();
  while (i != a.end() && j != b.end()) {
    if (*i < *j) {
      ++i;
    } else if (*j < *i) {
      ++j;
    } else {
      ++common;
      ++i;
      ++j;
    }
  }
  const std::size_t united = a.size() + b.size() - common;
  return united > 0 ? static_cast<double>(united - common) / static_cast<double>(united) : 0.0;
}

std::string_view rest_condition_name(RestCondition condition) {
  switch (condition) {
    case RestCondition::speed:
      return "speed";
    case RestCondition::coordination:
      return "coordination";
    case RestCondition::contacts:
      return "contacts";
    case RestCondition::none:
      break;
  }
  return "none";
}

bool RestDetector::update(const RestSample& sample) {
  const double time = sample.time;
  const double speed = std::max(sample.speed, 1e-300);  // log of it below
  // Decay-rate history: keep samples spaced by >= window/16 over the last window.
  const double window = decay_window > 0.0 ? decay_window : std::max(0.1 * time, 1e-300);
  if (history.empty() || time - history.back().first >= window / 16.0) history.emplace_back(time, std::log(speed));
  while (history.size() > 2 && time - history[1].first >= window) history.pop_front();

  last_speed = sample.speed;
  if (sample.speed > criterion.speed) {
    armed = true;
    if (window_start) last_failure = RestCondition::speed;
    window_start.reset();
    last_coordination_change = 0.0;
    last_contact_change = 0.0;
    return false;
  }
  if (!armed) return false;
  if (window_start) {
    last_coordination_change = std::abs(sample.coordination - reference_coordination);
    last_contact_change = contact_change_fraction(sample.pairs, reference_pairs);
    RestCondition failed = RestCondition::none;
    // One contact moves Z by 2 / N_p: 0.074 with 27 grains. A small scene is not held up by one
    // or two contacts that come and go: the bound is at least two contacts' worth.
    const double grains = sample.grains > 0 ? static_cast<double>(sample.grains) : 1.0;
    if (last_coordination_change > std::max(criterion.coordination_change, 4.0 / grains)) {
      failed = RestCondition::coordination;
    } else if (last_contact_change > criterion.contact_change) {
      failed = RestCondition::contacts;
    }
    if (failed != RestCondition::none) {
      // Still rearranging: this step becomes the reference of a new window.
      last_failure = failed;
      window_start.reset();
    }
  }
  if (!window_start) {
    window_start = time;
    reference_coordination = sample.coordination;
    reference_pairs = sample.pairs;
  }
  return time - *window_start >= criterion.duration;
}

std::optional<double> RestDetector::estimated_rest_time() const {
  if (!armed || history.size() < 3) return std::nullopt;
  const auto& [t_now, log_now] = history.back();
  if (window_start) return *window_start + criterion.duration;
  // Least-squares slope of ln s against t over the history: s decays as exp(-t/tau), tau = -1/slope.
  double mean_t = 0.0;
  double mean_y = 0.0;
  for (const auto& [t, y] : history) {
    mean_t += t;
    mean_y += y;
  }
  const auto n = static_cast<double>(history.size());
  mean_t /= n;
  mean_y /= n;
  double stt = 0.0;
  double sty = 0.0;
  for (const auto& [t, y] : history) {
    stt += (t - mean_t) * (t - mean_t);
    sty += (t - mean_t) * (y - mean_y);
  }
  if (!(stt > 0.0)) return std::nullopt;
  const double slope = sty / stt;
  if (!(slope < 0.0)) return std::nullopt;  // not decaying (still rising, or a plateau above the threshold)
  const double remaining = log_now - std::log(criterion.speed);
  return t_now + std::max(0.0, remaining) / -slope + criterion.duration;
}

bool rest_starts_armed(const Model& model, const State& state) {
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_grain(b) || model.is_fixed(b)) continue;
    if (state.velocity[b] != Vec3::Zero() || state.angular_velocity[b] != Vec3::Zero()) return true;
  }
  return false;
}

std::string describe_rest_criterion(const RestCriterion& criterion) {
  const std::string which =
      criterion.quantile >= 1.0 ? std::string("max") : fmt::format("p{:.4g}", 100.0 * criterion.quantile);
  return fmt::format("{}(|v| + |w| r) < {:.3g} m/s, |dZ| <= {:.3g}, contacts changed <= {:.3g}% for {:.4g} s", which,
                     criterion.speed, criterion.coordination_change, 100.0 * criterion.contact_change,
                     criterion.duration);
}

double eta_seconds(double elapsed_wall, double start_time, double time_now, double target_time) {
  const double done = time_now - start_time;
  if (!(done > 0.0) || !(elapsed_wall > 0.0)) return -1.0;
  return elapsed_wall / done * std::max(0.0, target_time - time_now);
}

std::optional<std::string> end_time_problem(double end_time, double start_time, double time_step) {
  const double steps = (end_time - start_time) / time_step;
  if (!std::isfinite(end_time) || !std::isfinite(steps) || steps > max_run_steps) {
    return fmt::format(
        "expected an end time at most 10^12 steps of dt = {:.6g} s after t = {:.6g} s (<= {:.6g} s), got {:.6g} s",
        time_step, start_time, start_time + max_run_steps * time_step, end_time);
  }
  if (end_time < start_time + time_step) {
    return fmt::format("expected an end time at least one step of dt = {:.6g} s after t = {:.6g} s, got {:.6g} s",
                       time_step, start_time, end_time);
  }
  return std::nullopt;
}

}  // namespace rubble
