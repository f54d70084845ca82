#include "simulation/run.hpp"

#include <chrono>
#include <cmath>
#include <fmt/format.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <optional>
#include <stdexcept>
#include <ostream>

#include "postprocessing/metrics.hpp"
#include "postprocessing/run_file.hpp"
#include "postprocessing/vtk_output.hpp"
#include "simulation/output_lock.hpp"
#include "simulation/run_control.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_between(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

std::string format_duration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const auto s = static_cast<long long>(seconds + 0.5);
  if (s >= 3600) return fmt::format("{}h{:02}m", s / 3600, (s % 3600) / 60);
  if (s >= 60) return fmt::format("{}m{:02}s", s / 60, s % 60);
  return fmt::format("{}s", s);
}

/// Steps between snapshots from the output options.
std::int64_t snapshot_period(const RunOptions& run, std::int64_t total_steps) {
  if (run.output.snapshot_every_steps > 0) return run.output.snapshot_every_steps;
  if (run.output.snapshot_interval > 0.0) {
    return std::max<std::int64_t>(1, std::llround(run.output.snapshot_interval / run.step.integrator.time_step));
  }
  return std::max<std::int64_t>(1, total_steps / 100);
}

/// The runaway bound on body b's speed (m/s), or a negative number when there is none.
double speed_limit(const Model& model, std::size_t b, double h, double max_speed) {
  if (max_speed != 0.0) return max_speed;  // explicit bound, or < 0: disabled
  // A grain that moves farther than its bounding radius in one step can pass through a
  // neighbour or a wall between two detections: the contact law is no longer enforced.
  return model.bounding_radius[b] / h;
}

/// A bad body and what is wrong with it.
struct Problem {
  std::size_t body = 0;
  std::string what;
};

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
    if (!c.delassus.allFinite() || !std::isfinite(c.normal_velocity_target) || !std::isfinite(c.normal_velocity_before)) {
      problem = {contact_body(c), fmt::format("contact with body {}: non-finite Delassus block or target velocity",
                                              c.id.body_a)};
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
    const bool ok = std::isfinite(model.mass[b]) && model.mass[b] > 0.0 && model.inverse_mass[b] > 0.0 &&
                    std::isfinite(model.inverse_mass[b]) && model.principal_inertia[b].allFinite() &&
                    (model.principal_inertia[b].array() > 0.0).all() && std::isfinite(model.bounding_radius[b]);
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
  const std::string reason = what.substr(at + marker.size(), end == std::string::npos ? std::string::npos : end - at - marker.size());
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

}  // namespace

RunSummary run_scene(const Scene& scene, const RunControl& control) { return run_scene(scene, scene.state, control); }

std::vector<RunParameter> run_parameters(const Scene& scene, std::int64_t snapshot_period) {
  const RunOptions& run = scene.run;
  const DetectionOptions& detection = run.step.detection;
  const double alert = resolve_alert_distance(scene.model, detection);
  std::vector<RunParameter> parameters{
      {"time_step", run.step.integrator.time_step, "s", run.automatic_time_step},
      {"alert_distance", alert, "m", detection.alert_distance <= 0.0},
      {"pair_list_margin", detection.pair_list_margin < 0.0 ? alert : detection.pair_list_margin, "m",
       detection.pair_list_margin < 0.0},
      {"snapshot_every_steps", static_cast<double>(snapshot_period), "1",
       run.output.snapshot_every_steps <= 0 && run.output.snapshot_interval <= 0.0}};
  if (run.until_rest) {
    parameters.push_back({"rest_speed", run.rest.speed, "m/s", run.automatic_rest_speed});
    parameters.push_back({"rest_quantile", run.rest.quantile, "1", false});
    parameters.push_back(
        {"rest_coordination_change", run.rest.coordination_change, "1", run.automatic_rest_coordination_change});
    parameters.push_back({"rest_contact_change", run.rest.contact_change, "1", false});
    parameters.push_back({"rest_duration", run.rest.duration, "s", run.automatic_rest_duration});
  }
  return parameters;
}

SeriesRow series_row(const Model& model, const State& state, const StepReport& report, const GravitySettings& gravity,
                     double wall_seconds, std::optional<double>& potential) {
  SeriesRow row;
  row.step = state.step;
  row.time = state.time;
  row.kinetic_energy = kinetic_energy(model, state);
  row.contacts = static_cast<std::int64_t>(report.contacts);
  row.active_contacts = static_cast<std::int64_t>(report.solver.active_contacts);
  row.iterations = report.solver.iterations;
  row.residual = report.solver.residual;
  row.wall_seconds = wall_seconds;
  if (report.potential_energy_known) {
    potential = report.potential_energy;
  } else if (potential) {
    *potential -= report.work_of_held_field;
  } else {
    potential = gravitational_potential_energy(model, state, gravity);
  }
  row.potential_energy = *potential;
  row.total_energy = row.kinetic_energy + row.potential_energy;
  const GrainMomenta momenta = grain_momenta(model, state);
  row.linear_momentum = momenta.linear;
  row.angular_momentum = momenta.angular;
  row.stage_seconds = report.stage_seconds;
  return row;
}

RunSummary run_scene(const Scene& scene, State initial_state, const RunControl& control) {
  const Model& model = scene.model;
  const RunOptions& run = scene.run;
  const double h = run.step.integrator.time_step;
  const double initial_time = initial_state.time;
  State state = std::move(initial_state);
  StepWorkspace workspace;
  RunSummary summary;
  RunProgress progress;
  check_mass_properties(model);

  const fs::path directory = run.output.directory;
  // The folder is ours before anything in it is opened or truncated (output_lock.hpp), and stays
  // ours until the run file is closed: the lock is declared before `file`, so it outlives it.
  const OutputFolderLock lock = OutputFolderLock::acquire(directory);
  if (lock.taken_over_from() && control.warnings) {
    *control.warnings << fmt::format("rubble run: {}: took over the stale lock of pid {} (that run is gone)\n",
                                     lock.file().string(), *lock.taken_over_from());
    control.warnings->flush();
  }
  summary.run_file = directory / "run.h5";
  const fs::path checkpoints = checkpoint_folder(directory);
  std::vector<std::string_view> stage_names;
  for (std::size_t s = 0; s < static_cast<std::size_t>(Stage::count); ++s) stage_names.push_back(stage_name(static_cast<Stage>(s)));

  // The end step follows from the scene's initial state and the end time, the same way in a new
  // run and in a resumed one (whose scene is parsed from the same text).
  // A step count past max_run_steps (or not finite) would not fit the cast below: refused, as
  // the scene file's and the command line's checks refuse it (run_control.hpp).
  // A resumed run counts from the time its first session started (the scene's initial time, or the
  // state a branch started from), which the checkpoint keeps.
  const double first_time = control.resume != nullptr ? control.resume->progress.first_time : initial_time;
  const double wanted_steps = (run.end_time - first_time) / h;
  if (!std::isfinite(wanted_steps) || wanted_steps > max_run_steps) {
    throw std::invalid_argument(fmt::format("end time {:.6g} s: {:.6g} steps of dt = {:.6g} s, expected at most 10^12",
                                            run.end_time, wanted_steps, h));
  }
  const auto total_steps = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil(wanted_steps - 1e-9)));
  std::optional<RunFile> file;
  // A new run file opens with a snapshot of the state it starts from, written once the VTK
  // series (if any) exists too: a new run, or a resumed one whose run file had to be replaced.
  bool first_snapshot_pending = control.resume == nullptr;
  std::int64_t last_checkpoint_step = -1;
  // Every write of the output goes through `output`: a failure (disk full, I/O error) stops the
  // run with an OutputError that says where it stopped and what is left to resume from.
  const auto output = [&](auto&& write) {
    try {
      write();
    } catch (const std::runtime_error& error) {
      const std::string resume =
          last_checkpoint_step >= 0
              ? fmt::format("the last checkpoint (step {}) is intact: free space (or fix the cause), then go on with "
                            "rubble run --resume {}",
                            last_checkpoint_step, directory.string())
              : std::string("no checkpoint was written yet: free space (or fix the cause) and run again");
      throw OutputError(fmt::format("writing the output failed at step {}: {}. The run stopped; {}", state.step,
                                    short_reason(error.what()), resume));
    }
  };
  if (control.resume != nullptr) {
    const Checkpoint& from = *control.resume;
    if (from.state.body_count() != model.body_count()) {
      throw CheckpointError(fmt::format("checkpoint of {} bodies, the scene has {}", from.state.body_count(),
                                        model.body_count()));
    }
    state = from.state;
    workspace.carry = from.carry;
    progress = from.progress;  // the snapshot period stays that of the first session
    last_checkpoint_step = state.step;
    // Resumed from an earlier checkpoint (--from-step, or newer ones damaged): the later ones
    // belong to the history this run now replaces; set aside, they are neither kept by the
    // retention as "newest" nor picked by a later --resume.
    const std::vector<fs::path> superseded = set_aside_checkpoints_after(checkpoints, state.step);
    if (!superseded.empty() && control.warnings) {
      *control.warnings << fmt::format("rubble run: note: {} later checkpoint(s) set aside as *.ckpt.superseded (the run "
                                       "goes on from step {})\n",
                                       superseded.size(), state.step);
    }
    std::string unusable;  // why run.h5 cannot be reopened ("" when it can)
    if (!fs::exists(summary.run_file)) {
      unusable = "it is missing";
    } else {
      try {
        file.emplace(RunFile::reopen(summary.run_file, state.step, stage_names));
      } catch (const std::runtime_error& error) {
        file.reset();
        unusable = short_reason(error.what());
      }
    }
    if (!unusable.empty()) {
      // The checkpoint holds everything the run needs; run.h5 only holds its history. A run file
      // damaged by a failed write (disk full) or a crash during a flush, or deleted, must not
      // block the run: it is moved aside and the series goes on in a new run.h5 that starts at
      // the checkpoint (a snapshot of its state, then a row per step after it).
      fs::path aside;
      if (fs::exists(summary.run_file)) {
        aside = directory / fmt::format("run.h5.damaged-at-step-{}", state.step);
        std::error_code ignored;
        fs::rename(summary.run_file, aside, ignored);
      }
      const std::vector<RunParameter> parameters = run_parameters(scene, progress.snapshot_period);
      output([&] {
        file.emplace(RunFile::create(summary.run_file, model, control.scene_text, stage_names, parameters));
      });
      first_snapshot_pending = true;
      progress.series_rows = 0;
      progress.snapshots = 0;
      if (control.warnings) {
        *control.warnings << fmt::format(
            "rubble run: warning: {} cannot be reopened ({}){}; the series goes on in a new {} from step {} (its "
            "first snapshot is the checkpoint's state)\n",
            summary.run_file.string(), unusable, aside.empty() ? "" : "; moved to " + aside.string(),
            summary.run_file.string(), state.step);
      }
    }
    if (file->series_rows() != progress.series_rows || file->snapshot_count() != progress.snapshots) {
      throw CheckpointError(fmt::format(
          "{}: has {} series rows and {} snapshots up to step {}, the checkpoint expects {} and {}: the run file "
          "does not belong to this checkpoint",
          summary.run_file.string(), file->series_rows(), file->snapshot_count(), state.step, progress.series_rows,
          progress.snapshots));
    }
  } else {
    progress.first_step = state.step;
    progress.first_time = state.time;
    progress.snapshot_period = snapshot_period(run, total_steps);
    const std::vector<RunParameter> parameters = run_parameters(scene, progress.snapshot_period);
    output([&] {
      file.emplace(RunFile::create(summary.run_file, model, control.scene_text, stage_names, parameters));
    });
  }
  output([&] { file->hold_metadata_until_flush(); });
  // [output] vtk = true: the ParaView series in DIR/vtk, one file set per snapshot of the run
  // file, written with it; a resumed run goes on after the snapshots the run file kept.
  std::optional<VtkSeries> vtk;
  if (run.output.write_vtk) {
    output([&] {
      vtk.emplace(directory / "vtk", model, VtkSeriesOptions{h, 0.0, file->snapshot_times()});
    });
  }
  // Writes a snapshot of the current state to the run file and the VTK series.
  const auto write_snapshot = [&](bool interrupted) {
    output([&] {
      file->write_snapshot(state, workspace.carry.contacts, interrupted);
      if (vtk) vtk->write(state, workspace.carry.contacts);
    });
  };
  progress.end_step = progress.first_step + total_steps;
  summary.first_step = state.step;

  // until = "rest" (run_control.hpp): stop once the grains' speeds, Z and contacts held still long
  // enough. A resumed run takes the watcher's memory from the checkpoint.
  RestDetector rest;
  rest.criterion = run.rest;
  rest.armed = control.rest_armed || rest_starts_armed(model, state);
  if (control.resume != nullptr) {
    restore_rest_watch(control.resume->rest, rest);
    // A run that ended at rest, resumed to go on (--end-time), would stop again at its first step:
    // its quiet window already lasted the duration. So would one whose thresholds were changed.
    // The window starts afresh at the next step: rest must hold for a whole duration again.
    const bool ended_at_rest = rest.window_start && state.time - *rest.window_start >= rest.criterion.duration;
    if (ended_at_rest || control.rest_overridden) rest.window_start.reset();
    if (ended_at_rest && run.until_rest && control.progress) {
      *control.progress << "rubble run: the checkpoint's run had ended at rest; the rest watcher starts a new "
                           "window (with --until end_time the run goes on to its end time)\n";
    }
    if (control.rest_overridden) {
      output([&] { file->set_parameters(run_parameters(scene, progress.snapshot_period)); });
    }
  }

  const auto write_checkpoint_now = [&] {
    file->flush();  // the run file first: the checkpoint then never promises rows that are not on disk
    progress.series_rows = file->series_rows();
    progress.snapshots = file->snapshot_count();
    // Saved from the run's own objects through a view and streamed to the file: no copy of the
    // state, contacts or detection memory, so a checkpoint adds ~1 MiB to the run's working set.
    const RestWatch saved_rest = save_rest_watch(rest);
    const CheckpointView checkpoint{control.scene_text, control.scene_source, run.end_time, run.seed,
                                    state,              workspace.carry,      progress,     saved_rest};
    summary.last_checkpoint =
        write_checkpoint(checkpoints, checkpoint, control.checkpoints_kept, run.output.keep_checkpoint_every);
    last_checkpoint_step = state.step;
  };

  std::size_t grain_count = 0;
  for (std::size_t b = 0; b < model.body_count(); ++b) grain_count += model.is_grain(b) ? 1 : 0;
  const double start_time = state.time;

  const auto start = Clock::now();
  auto last_progress = start;
  auto last_checkpoint_time = start;
  if (first_snapshot_pending) write_snapshot(false);

  State before;  // the state at the start of the step, to locate a failure
  std::optional<double> potential;  // the grains' potential energy after the last step, J
  const double alert_distance = resolve_alert_distance(model, run.step.detection);
  bool tunnelling_warned = false;
  while (state.step < progress.end_step) {
    const auto step_start = Clock::now();
    before = state;
    StepReport report;
    std::optional<Problem> problem;
    try {
      report = step(model, state, workspace, run.step);
    } catch (const std::runtime_error&) {
      // A non-finite velocity makes the midpoint configuration non-finite, and detection refuses
      // it before the end-of-step check below: report it as that check would.
      problem = check_state(model, state, h, control.max_speed);
      if (!problem) throw;
    }
#if defined(__GLIBC__)
    // Every 64 steps the heap's free pages go back to the system. While a run's contact list
    // grows it lives in the heap, until glibc gives blocks over 32 MiB their own mappings; the heap
    // space it leaves behind is never trimmed (glibc's trim threshold has grown with it) and stayed
    // resident: 50 MB, a fifth of the peak at 1e5 spheres (bench/RESULTS.md, "Memory per grain").
    // The step's temporaries take their pages back once after each trim, so it costs nothing
    // measurable; results do not depend on it.
    if (state.step % 64 == 0) malloc_trim(0);
#endif
    if (!problem) problem = check_state(model, state, h, control.max_speed);
    if (problem) {
      const std::string stage = locate_failure(model, before, workspace, run.step, control.max_speed, *problem);
      try {
        file->set_status(RunStatus::numerical_failure,
                       fmt::format("numerical failure at step {} (t = {:.6g} s): body {}: {}", state.step, state.time,
                                   problem->body, problem->what));
        file->flush();  // what the run wrote up to the failure, if the disk takes it
      } catch (const std::runtime_error&) {
        // The numerical failure is the news; a run file that cannot be flushed is secondary.
      }
      throw NumericalFailure(fmt::format(
          "step {} (t = {:.6g} s), stage {}: body {}: {}. The run stopped; the last checkpoint ({}) is intact.",
          state.step, state.time, stage, problem->body, problem->what,
          last_checkpoint_step >= 0 ? fmt::format("step {}", last_checkpoint_step) : std::string("none")));
    }
    const auto step_end = Clock::now();
    const double step_seconds = seconds_between(step_start, step_end);

    const SeriesRow row = series_row(model, state, report, run.step.gravity, step_seconds, potential);
    // A grain that moves further than the alert distance in one step can cross a wall or another
    // grain between two detections (tunnelling): warned once, with the step and the body.
    if (!tunnelling_warned && control.progress) {
      for (std::size_t b = 0; b < model.body_count(); ++b) {
        if (model.is_fixed(b)) continue;
        const double travel = h * state.velocity[b].norm();
        if (travel > alert_distance) {
          *control.progress << fmt::format(
              "warning: step {} (t = {:.6g} s): body {} moved {:.3g} m in one step, more than the alert distance "
              "{:.3g} m; it may pass through walls or grains undetected: lower [time] dt or raise "
              "[detection] alert_distance\n",
              state.step, state.time, b, travel, alert_distance);
          tunnelling_warned = true;
          break;
        }
      }
    }
    output([&] { file->append_series(row); });

    for (std::size_t s = 0; s < summary.stage_seconds.size(); ++s) summary.stage_seconds[s] += report.stage_seconds[s];
    summary.polish_attempts += report.solver.polish_attempts;
    progress.iteration_sum += report.solver.iterations;
    progress.max_residual = std::max(progress.max_residual, report.solver.residual);
    if (!report.solver.converged) ++progress.unconverged_steps;
    progress.wall_seconds += step_seconds;
    const std::int64_t done = state.step - progress.first_step;
    const bool at_rest = run.until_rest && grain_count > 0 &&
                         rest.update(rest_sample(model, state, workspace.carry.contacts, run.rest.quantile));
    const bool at_end = state.step == progress.end_step || at_rest;
    if (done % progress.snapshot_period == 0 || at_end) write_snapshot(false);

    const bool stop = control.stop_requested != nullptr && control.stop_requested->load(std::memory_order_relaxed) != 0;
    const bool by_steps = control.checkpoint_every_steps > 0 && done % control.checkpoint_every_steps == 0;
    const bool by_time =
        control.checkpoint_interval > 0.0 && seconds_between(last_checkpoint_time, step_end) >= control.checkpoint_interval;
    if (stop || by_steps || by_time || at_end) {
      output(write_checkpoint_now);
      last_checkpoint_time = Clock::now();
    }
    // The state at a stop by signal, as the run file's last snapshot (marked @interrupted), after
    // the checkpoint: the checkpoint does not count it, and a resumed run removes it
    // (RunFile::reopen), so that its run file equals an uninterrupted run's.
    if (stop && file->last_snapshot_step() != state.step) write_snapshot(true);

    const auto now = Clock::now();
    summary.output_seconds += seconds_between(step_end, now);
    if (control.progress && (seconds_between(last_progress, now) >= run.output.progress_interval || at_end || stop)) {
      const double elapsed = seconds_between(start, now);
      const auto session_steps = static_cast<double>(state.step - summary.first_step);
      double eta = elapsed / session_steps * static_cast<double>(progress.end_step - state.step);
      std::string eta_text = format_duration(eta);
      if (run.until_rest) {
        // The end is the rest time, estimated from the energy's decay; the end time caps it.
        const std::optional<double> rest_time = rest.estimated_rest_time();
        eta = eta_seconds(elapsed, start_time, state.time, std::min(rest_time.value_or(run.end_time), run.end_time));
        eta_text = rest_time ? format_duration(eta) + " (to rest)" : "? (not decaying yet; at most " + format_duration(eta) + ")";
        if (at_rest) eta_text = "0s (at rest)";
      }
      *control.progress << fmt::format(
          "step {:>8}/{}  t = {:.4g} s  contacts {:>6}  iterations {:>4}  residual {:.1e}  Ek {:.3e} J{}  elapsed {}  "
          "ETA {}\n",
          state.step, progress.end_step, state.time, report.contacts, report.solver.iterations, report.solver.residual,
          row.kinetic_energy, run.until_rest ? "  " + rest_progress(rest, state.time) : std::string(),
          format_duration(elapsed), eta_text);
      control.progress->flush();
      last_progress = now;
    }
    if (stop) {
      summary.interrupted = true;
      break;
    }
    if (at_rest) {
      summary.reached_rest = true;
      if (control.progress) *control.progress << "rubble run: " << rest_reason(rest, state.time) << "\n";
      break;
    }
  }
  if (last_checkpoint_step != state.step) output(write_checkpoint_now);  // e.g. a run of zero steps
  const RunStatus status = summary.interrupted   ? RunStatus::interrupted
                           : summary.reached_rest ? RunStatus::at_rest
                                                  : RunStatus::end_time;
  // Which criterion ended the run, in words (/run@stop_reason, docs/output-format.md).
  if (summary.interrupted) {
    summary.stop_reason = fmt::format("stopped by a signal at step {} (t = {:.6g} s)", state.step, state.time);
  } else if (summary.reached_rest) {
    summary.stop_reason = rest_reason(rest, state.time);
  } else {
    summary.stop_reason = fmt::format("end time reached at t = {:.6g} s (step {})", state.time, state.step);
    if (run.until_rest) {
      summary.stop_reason += "; not at rest: " + (rest.window_start ? fmt::format("quiet for {:.4g} s of {:.4g} s",
                                                                                 state.time - *rest.window_start,
                                                                                 run.rest.duration)
                                                                    : std::string("speed above the rest speed")) +
                             fmt::format(" (last failed condition: {})", rest_condition_name(rest.last_failure));
    }
  }
  output([&] {
    file->set_status(status, summary.stop_reason);
    file->flush();
  });

  summary.final_step = state.step;
  summary.steps = state.step - summary.first_step;
  summary.simulated_time = state.time;
  summary.wall_seconds = seconds_between(start, Clock::now());
  const std::int64_t run_steps = state.step - progress.first_step;
  summary.mean_iterations = run_steps > 0 ? progress.iteration_sum / static_cast<double>(run_steps) : 0.0;
  summary.max_residual = progress.max_residual;
  summary.unconverged_steps = progress.unconverged_steps;
  summary.snapshots = file->snapshot_count();
  summary.state_hash = state_hash(state);
  return summary;
}

}  // namespace rubble
