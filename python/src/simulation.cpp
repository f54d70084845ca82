#include "simulation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "simulation/run.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::python {
namespace {

/// The stage names, the columns of the run file's /series/stage_seconds.
std::vector<std::string_view> stage_names() {
  std::vector<std::string_view> names;
  for (std::size_t s = 0; s < stage_count; ++s) names.push_back(stage_name(static_cast<Stage>(s)));
  return names;
}

/// The grains' mass properties must be finite and positive, as run_scene requires.
void check_mass_properties(const Model& model) {
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_grain(b)) continue;
    const bool ok = std::isfinite(model.mass[b]) && model.mass[b] > 0.0 && std::isfinite(model.inverse_mass[b]) &&
                    model.inverse_mass[b] > 0.0 && model.principal_inertia[b].allFinite() &&
                    (model.principal_inertia[b].array() > 0.0).all() && std::isfinite(model.bounding_radius[b]);
    if (!ok) {
      throw std::invalid_argument(fmt::format(
          "body {} (a grain): mass {} kg, bounding radius {} m: expected finite positive values (is its size or "
          "density out of range?)",
          b, model.mass[b], model.bounding_radius[b]));
    }
  }
}

}  // namespace

Simulation::Simulation(Scene scene, std::string scene_text, std::string scene_source)
    : scene_(std::move(scene)), scene_text_(std::move(scene_text)), scene_source_(std::move(scene_source)) {
  check_mass_properties(scene_.model);
  if (scene_.inflow.active()) {
    // Its grains enter between steps in the run loop of rubble run (simulation/inflow.hpp), which
    // this class does not share: refused rather than stepped with the grains still waiting.
    throw std::invalid_argument(
        "the scene has [[inflow]] entries, which only `rubble run` inserts: run it with "
        "rubble run, then read its run.h5 or branch from it");
  }
  // The state is moved out of the scene: one copy of it, which the numpy views point into.
  state_ = std::move(scene_.state);
  scene_.state = State{};
  for (std::size_t b = 0; b < scene_.model.body_count(); ++b) grain_count_ += scene_.model.is_grain(b) ? 1 : 0;
  free_inverse_mass_ = scene_.model.inverse_mass;
  free_inverse_inertia_ = scene_.model.inverse_inertia;
  rest_.criterion = scene_.run.rest;
  rest_.armed = rest_starts_armed(scene_.model, state_);
  progress_.first_step = state_.step;
  progress_.first_time = state_.time;
}

Simulation Simulation::from_checkpoint(const Checkpoint& checkpoint) {
  Scene scene = parse_scene(checkpoint.scene_text, checkpoint.scene_source);
  if (checkpoint.state.body_count() != scene.model.body_count()) {
    throw CheckpointError(fmt::format("checkpoint of {} bodies, its scene has {}", checkpoint.state.body_count(),
                                      scene.model.body_count()));
  }
  scene.run.end_time = checkpoint.end_time;
  Simulation simulation(std::move(scene), checkpoint.scene_text, checkpoint.scene_source);
  simulation.state_ = checkpoint.state;
  simulation.workspace_.carry = checkpoint.carry;
  simulation.progress_ = checkpoint.progress;
  restore_rest_watch(checkpoint.rest, simulation.rest_);
  return simulation;
}

Simulation Simulation::branch() const {
  Simulation copy;
  copy.scene_ = scene_;
  copy.scene_text_ = scene_text_;
  copy.scene_source_ = scene_source_;
  copy.scene_modified_ = scene_modified_;
  copy.state_ = state_;
  copy.workspace_ = workspace_;
  copy.last_report_ = last_report_;
  copy.total_stage_seconds_ = total_stage_seconds_;
  copy.grain_count_ = grain_count_;
  copy.free_inverse_mass_ = free_inverse_mass_;
  copy.free_inverse_inertia_ = free_inverse_inertia_;
  copy.watch_rest_ = watch_rest_;
  copy.at_rest_ = at_rest_;
  copy.rest_ = rest_;
  copy.progress_ = progress_;
  return copy;
}

namespace {

/// The first body whose position, orientation or velocity is not finite (body_count() if none).
std::size_t first_non_finite_body(const State& state) {
  for (std::size_t b = 0; b < state.body_count(); ++b) {
    if (!state.position[b].allFinite() || !state.orientation[b].coeffs().allFinite() ||
        !state.velocity[b].allFinite() || !state.angular_velocity[b].allFinite()) {
      return b;
    }
  }
  return state.body_count();
}

}  // namespace

const StepReport& Simulation::advance() {
  const auto start = std::chrono::steady_clock::now();
  try {
    last_report_ = step(scene_.model, state_, workspace_, scene_.run.step);
  } catch (const std::runtime_error&) {
    // As run_scene: a non-finite state makes detection refuse the midpoint configuration; report
    // it as the end-of-step check below would.
    if (first_non_finite_body(state_) == state_.body_count()) throw;
  }
  const double step_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (const std::size_t b = first_non_finite_body(state_); b < state_.body_count()) {
    throw NumericalFailure(fmt::format("step {} (t = {:.6g} s): body {}: non-finite position, orientation or velocity",
                                       state_.step, state_.time, b));
  }
  for (std::size_t s = 0; s < stage_count; ++s) total_stage_seconds_[s] += last_report_.stage_seconds[s];
  progress_.iteration_sum += last_report_.solver.iterations;
  progress_.max_residual = std::max(progress_.max_residual, last_report_.solver.residual);
  if (!last_report_.solver.converged) ++progress_.unconverged_steps;
  progress_.wall_seconds += step_seconds;

  if (!record_ && !watch_rest_) return last_report_;
  if (watch_rest_ && grain_count_ > 0) {
    at_rest_ = rest_.update(rest_sample(scene_.model, state_, workspace_.carry.contacts, scene_.run.rest.quantile)) ||
               at_rest_;
  }
  if (record_) {
    const SeriesRow row =
        series_row(scene_.model, state_, last_report_, scene_.run.step.gravity, step_seconds, potential_energy_);
    record_->append_series(row);
    if ((state_.step - record_first_step_) % snapshot_period_ == 0 || at_rest_) write_snapshot();
  }
  return last_report_;
}

std::int64_t Simulation::steps_to(double time) const {
  const double h = scene_.run.step.integrator.time_step;
  return std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil((time - state_.time) / h - 1e-9)));
}

void Simulation::record(const std::filesystem::path& directory, double end_time) {
  if (record_) throw std::runtime_error("already recording " + record_->path().string() + "; close it first");
  std::filesystem::create_directories(directory);
  const std::vector<std::string_view> names = stage_names();
  const OutputOptions& output = scene_.run.output;
  if (output.snapshot_every_steps > 0) {
    snapshot_period_ = output.snapshot_every_steps;
  } else if (output.snapshot_interval > 0.0) {
    snapshot_period_ =
        std::max<std::int64_t>(1, std::llround(output.snapshot_interval / scene_.run.step.integrator.time_step));
  } else {
    snapshot_period_ = std::max<std::int64_t>(1, steps_to(end_time) / 100);
  }
  const std::vector<RunParameter> parameters = run_parameters(scene_, snapshot_period_);
  record_.emplace(RunFile::create(directory / "run.h5", scene_.model, scene_text_, names, parameters));
  record_->hold_metadata_until_flush();
  record_vtk_.reset();
  if (output.write_vtk) {
    record_vtk_.emplace(directory / "vtk", scene_.model,
                        VtkSeriesOptions{scene_.run.step.integrator.time_step, 0.0, {}});
  }
  record_first_step_ = state_.step;
  progress_.first_step = state_.step;
  progress_.first_time = state_.time;
  potential_energy_.reset();  // the run loop's monitor starts afresh with the file
  progress_.snapshot_period = snapshot_period_;
  progress_.end_step = state_.step + steps_to(end_time);
  last_snapshot_step_ = -1;
  write_snapshot();
}

void Simulation::write_snapshot() {
  if (!record_ || last_snapshot_step_ == state_.step) return;
  record_->write_snapshot(state_, workspace_.carry.contacts);
  if (record_vtk_) record_vtk_->write(state_, workspace_.carry.contacts);
  last_snapshot_step_ = state_.step;
}

void Simulation::close_record() {
  if (!record_) return;
  write_snapshot();
  // As run_scene says why it ended; a script may also stop before either end ("closed").
  const RunStatus status = at_rest_                            ? RunStatus::at_rest
                           : state_.step >= progress_.end_step ? RunStatus::end_time
                                                               : RunStatus::closed;
  const std::string reason =
      status == RunStatus::at_rest ? fmt::format("at rest at t = {:.6g} s (step {})", state_.time, state_.step)
      : status == RunStatus::end_time
          ? fmt::format("end time reached at t = {:.6g} s (step {})", state_.time, state_.step)
          : fmt::format("closed by the script at t = {:.6g} s (step {})", state_.time, state_.step);
  record_->set_status(status, reason);
  record_->flush();
  record_.reset();
  record_vtk_.reset();
}

std::filesystem::path Simulation::record_path() const { return record_ ? record_->path() : std::filesystem::path(); }

std::filesystem::path Simulation::save_checkpoint(const std::filesystem::path& folder, int keep) {
  if (keep < 1) throw std::invalid_argument(fmt::format("keep: expected >= 1, got {}", keep));
  // The run's end step as the checkpoint format checks it (step within [first_step, end_step]).
  progress_.end_step = std::max(progress_.end_step, state_.step + steps_to(scene_.run.end_time));
  if (record_) {
    record_->flush();  // as the run loop: the checkpoint never promises rows that are not on disk
    progress_.series_rows = record_->series_rows();
    progress_.snapshots = record_->snapshot_count();
  }
  // A scene changed between steps is saved as it is now (every grain explicit), so that loading
  // the checkpoint runs on with the new time step and contact laws.
  std::string text = scene_text_;
  if (scene_modified_) {
    // scene_to_toml reads the grains' positions from scene.state: lend it the current state
    // (swapping vectors moves no element, so numpy views stay valid) and take it back.
    std::swap(scene_.state, state_);
    try {
      text = scene_to_toml(scene_);
    } catch (...) {
      std::swap(scene_.state, state_);
      throw;
    }
    std::swap(scene_.state, state_);
  }
  const RestWatch rest = save_rest_watch(rest_);
  const CheckpointView view{text,   scene_source_,    scene_.run.end_time, scene_.run.seed,
                            state_, workspace_.carry, progress_,           rest};
  return write_checkpoint(folder, view, keep);
}

void Simulation::set_fixed(std::size_t body, bool fixed) {
  Model& model = scene_.model;
  if (body >= model.body_count()) {
    throw std::out_of_range(fmt::format("body {}: expected an id < {}", body, model.body_count()));
  }
  if (!model.is_grain(body))
    throw std::invalid_argument(fmt::format("body {} is a wall: walls are always fixed", body));
  if (fixed) {
    model.inverse_mass[body] = 0.0;
    model.inverse_inertia[body] = Vec3::Zero();
    state_.velocity[body] = Vec3::Zero();
    state_.angular_velocity[body] = Vec3::Zero();
  } else {
    model.inverse_mass[body] = free_inverse_mass_[body];
    model.inverse_inertia[body] = free_inverse_inertia_[body];
  }
}

void Simulation::set_contact_law(int material_a, int material_b, const ContactLaw& law) {
  const int n = scene_.model.contact_laws.material_count;
  if (material_a < 0 || material_a >= n || material_b < 0 || material_b >= n) {
    throw std::out_of_range(fmt::format("materials ({}, {}): expected ids in [0, {})", material_a, material_b, n));
  }
  if (!(law.friction_coefficient >= 0.0) || !std::isfinite(law.friction_coefficient)) {
    throw std::invalid_argument(
        fmt::format("friction: expected a finite number >= 0, got {}", law.friction_coefficient));
  }
  if (!(law.normal_restitution >= 0.0 && law.normal_restitution <= 1.0)) {
    throw std::invalid_argument(
        fmt::format("restitution: expected a number in [0, 1], got {}", law.normal_restitution));
  }
  if (!(law.tangential_restitution >= 0.0 && law.tangential_restitution <= 1.0)) {
    throw std::invalid_argument(
        fmt::format("tangential_restitution: expected a number in [0, 1], got {}", law.tangential_restitution));
  }
  if (!(law.cohesion >= 0.0) || !std::isfinite(law.cohesion)) {
    throw std::invalid_argument(fmt::format("cohesion: expected a finite number >= 0 (N), got {}", law.cohesion));
  }
  if (!(law.work_of_adhesion >= 0.0) || !std::isfinite(law.work_of_adhesion)) {
    throw std::invalid_argument(
        fmt::format("work_of_adhesion: expected a finite number >= 0 (J/m^2), got {}", law.work_of_adhesion));
  }
  for (const auto& [name, value] :
       {std::pair{"rolling_friction", law.rolling_friction}, std::pair{"twisting_friction", law.twisting_friction}}) {
    if (!(value >= 0.0) || !std::isfinite(value)) {
      throw std::invalid_argument(fmt::format("{}: expected a finite number >= 0, got {}", name, value));
    }
  }
  if (law.resists_rotation()) {
    // As the scene file (simulation/scene_checks.cpp): rolling and twisting resistance act on
    // sphere contacts only, and a pair with a polyhedron material is refused.
    const Model& model = scene_.model;
    std::vector<bool> polyhedra(static_cast<std::size_t>(n), false), present(static_cast<std::size_t>(n), false);
    for (std::size_t body = 0; body < model.body_count(); ++body) {
      const auto material = static_cast<std::size_t>(model.material[body]);
      present[material] = true;
      if (model.shape_kind[body] == ShapeKind::polyhedron) polyhedra[material] = true;
    }
    const auto a = static_cast<std::size_t>(material_a), b = static_cast<std::size_t>(material_b);
    if ((polyhedra[a] && present[b]) || (polyhedra[b] && present[a])) {
      throw std::invalid_argument(fmt::format(
          "rolling_friction, twisting_friction: rolling and twisting resistance act on sphere contacts only, and "
          "material \"{}\" is used by polyhedron grains: expected 0 for a pair with a polyhedron material",
          model.materials[polyhedra[a] && present[b] ? a : b].name));
    }
  }
  scene_.model.contact_laws.set(material_a, material_b, law);
  scene_modified_ = true;
}

void Simulation::set_time_step(double h) {
  if (!(h > 0.0) || !std::isfinite(h))
    throw std::invalid_argument(fmt::format("dt: expected a finite number > 0, got {}", h));
  scene_.run.step.integrator.time_step = h;
  scene_.run.automatic_time_step = false;
  scene_modified_ = true;
}

PotentialSettings Simulation::potential_settings() const {
  // The same mapping as `rubble post` (apps/cmd_post.cpp): the central field has no potential
  // in the metrics yet.
  const GravitySettings& gravity = scene_.run.step.gravity;
  PotentialSettings potential;
  switch (gravity.kind) {
    case GravitySettings::Kind::none:
    case GravitySettings::Kind::central:
      potential.kind = PotentialSettings::Kind::none;
      break;
    case GravitySettings::Kind::uniform:
      potential.kind = PotentialSettings::Kind::uniform;
      potential.acceleration = gravity.acceleration;
      break;
    case GravitySettings::Kind::self:
      potential.kind = PotentialSettings::Kind::self;
      potential.gravitational_constant = gravity.self_gravity.G;
      potential.softening = gravity.self_gravity.softening.kind == gravity::Softening::Kind::plummer
                                ? gravity.self_gravity.softening.length
                                : 0.0;
      break;
  }
  return potential;
}

AggregateMetrics Simulation::metrics(const ContactMetricsOptions& options) const {
  if (!grain_sizes_) grain_sizes_ = grain_sizes(scene_.model);
  return compute_metrics(scene_.model, *grain_sizes_, state_, workspace_.carry.contacts, potential_settings(), options);
}

}  // namespace rubble::python
