#include "simulation/run.hpp"

#include <chrono>
#include <cmath>
#include <fmt/format.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <optional>
#include <ostream>
#include <stdexcept>

#include "postprocessing/metrics.hpp"
#include "postprocessing/run_file.hpp"
#include "postprocessing/vtk_output.hpp"
#include "simulation/output_lock.hpp"
#include "simulation/run_control.hpp"
#include "simulation/run_support.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace run_support;

double seconds_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

/// Steps between snapshots from the output options.
std::int64_t snapshot_period(const RunOptions& run, std::int64_t total_steps) {
  if (run.output.snapshot_every_steps > 0) return run.output.snapshot_every_steps;
  if (run.output.snapshot_interval > 0.0) {
    return std::max<std::int64_t>(1, std::llround(run.output.snapshot_interval / run.step.integrator.time_step));
  }
  return std::max<std::int64_t>(1, total_steps / 100);
}

/// The steps from `first_time` to the run's end time. A step count past max_run_steps (or not
/// finite) would not fit the cast: refused, as the scene file's and the command line's checks
/// refuse it (run_control.hpp).
std::int64_t steps_to_end(const RunOptions& run, double first_time) {
  const double h = run.step.integrator.time_step;
  const double wanted_steps = (run.end_time - first_time) / h;
  if (!std::isfinite(wanted_steps) || wanted_steps > max_run_steps) {
    throw std::invalid_argument(fmt::format("end time {:.6g} s: {:.6g} steps of dt = {:.6g} s, expected at most 10^12",
                                            run.end_time, wanted_steps, h));
  }
  return std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil(wanted_steps - 1e-9)));
}

/// One session of run_scene, in the pieces a run goes through: open a new run or resume one
/// (constructor), step and record (step_and_record), checkpoint (checkpoint_if_due), progress
/// (print_progress), finish (finish). The objects the loop works on are its members: the State,
/// the StepWorkspace (whose StepCarry a checkpoint saves), the run's bookkeeping (RunProgress),
/// the run file and the rest watcher.
class RunSession {
 public:
  RunSession(const Scene& scene, State initial_state, ContactList warm_start, const RunControl& control);
  /// Steps to the end (or rest, or a stop request) and returns the summary.
  RunSummary run();

 private:
  template <typename Write>
  void output(Write&& write);
  void open_new_run();
  void resume(const Checkpoint& from);
  void open_run_file_to_resume();
  void start_rest_watch();
  void write_snapshot(bool interrupted);
  void insert_inflow_grains();
  bool inflow_complete() const { return model_.body_count() == scene_.model.body_count(); }
  void write_checkpoint_now();
  bool step_and_record();
  StepReport take_step();
  [[noreturn]] void fail_numerically(Problem problem);
  void warn_tunnelling();
  void watch_sweep_cap(const StepReport& report);
  void account(const StepReport& report, double step_seconds);
  void checkpoint_if_due(std::int64_t done, Clock::time_point step_end, bool forced);
  void print_progress(const StepReport& report, const SeriesRow& row, Clock::time_point now, bool at_rest);
  std::string stop_reason() const;
  std::string inflow_progress() const;
  std::string stop_reason_before_inflow() const;
  RunSummary finish();

  const Scene& scene_;
  /// With an inflow: the model cut to the bodies in play (simulation/inflow.hpp), which gains
  /// each grain the inflow inserts; empty otherwise.
  Model in_play_;
  /// The model the step sees: scene.model, or in_play_ with an inflow.
  const Model& model_;
  const RunOptions& run_;
  /// The step's options: run_.step, with an inflow the alert distance resolved from the whole
  /// model (the bodies in play would give another value at each insertion).
  StepOptions step_options_;
  const RunControl& control_;
  const double h_;              ///< s, the time step
  const fs::path directory_;    ///< the output folder
  const fs::path checkpoints_;  ///< its checkpoint folder
  /// The folder is ours before anything in it is opened or truncated (output_lock.hpp), and stays
  /// ours until the run file is closed: declared before file_, so it outlives it.
  OutputFolderLock lock_;
  State state_;
  StepWorkspace workspace_;  ///< workspace_.carry goes from step to step and into checkpoints
  RunProgress progress_;
  RunSummary summary_;
  std::int64_t total_steps_ = 0;  ///< steps from the run's first time to its end time
  std::vector<std::string_view> stage_names_;
  std::optional<RunFile> file_;
  std::optional<VtkSeries> vtk_;  ///< [output] vtk = true: the ParaView series in DIR/vtk
  RestDetector rest_;             ///< until = "rest" (run_control.hpp)
  /// A new run file opens with a snapshot of the state it starts from, written once the VTK
  /// series (if any) exists too: a new run, or a resumed one whose run file had to be replaced.
  bool first_snapshot_pending_ = false;
  std::int64_t last_checkpoint_step_ = -1;
  std::size_t grain_count_ = 0;
  double start_time_ = 0.0;  ///< s, simulated time when this session started
  Clock::time_point start_, last_progress_, last_checkpoint_time_;
  State before_;                     ///< the state at the start of the step, to locate a failure
  std::optional<double> potential_;  ///< the grains' potential energy after the last step, J
  double alert_distance_ = 0.0;
  bool tunnelling_warned_ = false;
  /// The sweep-cap watch (watch_sweep_cap): steps of the current window, those of them that
  /// stopped at max_iterations, their largest residual, and whether the warning was given.
  struct SweepCapWindow {
    int steps = 0;                  ///< steps in the window so far
    int capped = 0;                 ///< of them, stopped at max_iterations
    double largest_residual = 0.0;  ///< the capped steps' largest end-of-step residual
    bool warned = false;            ///< the warning was given (once a run)
  } sweep_cap_;
  std::size_t inflow_waiting_ = 0;  ///< inflow grains due but not in play (no room in their region)
};

RunSession::RunSession(const Scene& scene, State initial_state, ContactList warm_start, const RunControl& control)
    : scene_(scene),
      model_(scene.inflow.active() ? in_play_ : scene.model),
      run_(scene.run),
      step_options_(scene.run.step),
      control_(control),
      h_(scene.run.step.integrator.time_step),
      directory_(scene.run.output.directory),
      checkpoints_(checkpoint_folder(directory_)),
      lock_(OutputFolderLock::acquire(directory_)),
      state_(std::move(initial_state)),
      first_snapshot_pending_(control.resume == nullptr) {
  if (lock_.taken_over_from() && control_.warnings) {
    *control_.warnings << fmt::format("rubble run: {}: took over the stale lock of pid {} (that run is gone)\n",
                                      lock_.file().string(), *lock_.taken_over_from());
    control_.warnings->flush();
  }
  summary_.run_file = directory_ / "run.h5";
  if (scene_.inflow.active()) {
    // The bodies in play: the scene's own, or those of the checkpoint's state.
    const std::size_t in_play =
        control_.resume != nullptr ? control_.resume->state.body_count() : scene_.inflow.first_body;
    if (in_play < scene_.inflow.first_body || in_play > scene_.model.body_count()) {
      throw CheckpointError(fmt::format("checkpoint of {} bodies, the scene has {} and {} inflow grains", in_play,
                                        scene_.inflow.first_body,
                                        scene_.model.body_count() - scene_.inflow.first_body));
    }
    in_play_ = model_prefix(scene_.model, in_play);
    state_ = state_prefix(state_, in_play);
    step_options_.detection.alert_distance = resolve_alert_distance(scene_.model, run_.step.detection);
  }
  for (std::size_t s = 0; s < static_cast<std::size_t>(Stage::count); ++s) {
    stage_names_.push_back(stage_name(static_cast<Stage>(s)));
  }
  // The end step follows from the run's first time and the end time, the same way in a new run
  // and in a resumed one (whose scene is parsed from the same text). A resumed run counts from
  // the time its first session started (the scene's initial time, or the state a branch started
  // from), which the checkpoint keeps.
  total_steps_ = steps_to_end(run_, control_.resume != nullptr ? control_.resume->progress.first_time : state_.time);
  if (control_.resume != nullptr) {
    resume(*control_.resume);
  } else {
    workspace_.carry.contacts = std::move(warm_start);
    open_new_run();
  }
  output([&] { file_->hold_metadata_until_flush(); });
  // A resumed run goes on after the snapshots the run file kept.
  if (run_.output.write_vtk) {
    output([&] { vtk_.emplace(directory_ / "vtk", model_, VtkSeriesOptions{h_, 0.0, file_->snapshot_times()}); });
  }
  progress_.end_step = progress_.first_step + total_steps_;
  summary_.first_step = state_.step;
  start_rest_watch();
}

/// Every write of the output goes through here: a failure (disk full, I/O error) stops the run
/// with an OutputError that says where it stopped and what is left to resume from.
template <typename Write>
void RunSession::output(Write&& write) {
  try {
    write();
  } catch (const std::runtime_error& error) {
    const std::string resume =
        last_checkpoint_step_ >= 0
            ? fmt::format(
                  "the last checkpoint (step {}) is intact: free space (or fix the cause), then go on with "
                  "rubble run --resume {}",
                  last_checkpoint_step_, directory_.string())
            : std::string("no checkpoint was written yet: free space (or fix the cause) and run again");
    throw OutputError(fmt::format("writing the output failed at step {}: {}. The run stopped; {}", state_.step,
                                  short_reason(error.what()), resume));
  }
}

void RunSession::open_new_run() {
  progress_.first_step = state_.step;
  progress_.first_time = state_.time;
  progress_.snapshot_period = snapshot_period(run_, total_steps_);
  const std::vector<RunParameter> parameters = run_parameters(scene_, progress_.snapshot_period);
  output([&] {
    file_.emplace(RunFile::create(summary_.run_file, scene_.model, control_.scene_text, stage_names_, parameters));
  });
}

void RunSession::resume(const Checkpoint& from) {
  if (from.state.body_count() != model_.body_count()) {  // with an inflow: in_play_ is the checkpoint's prefix
    throw CheckpointError(
        fmt::format("checkpoint of {} bodies, the scene has {}", from.state.body_count(), model_.body_count()));
  }
  state_ = from.state;
  workspace_.carry = from.carry;
  progress_ = from.progress;  // the snapshot period stays that of the first session
  last_checkpoint_step_ = state_.step;
  // Resumed from an earlier checkpoint (--from-step, or newer ones damaged): the later ones
  // belong to the history this run now replaces; set aside, they are neither kept by the
  // retention as "newest" nor picked by a later --resume.
  const std::vector<fs::path> superseded = set_aside_checkpoints_after(checkpoints_, state_.step);
  if (!superseded.empty() && control_.warnings) {
    *control_.warnings << fmt::format(
        "rubble run: note: {} later checkpoint(s) set aside as *.ckpt.superseded (the "
        "run goes on from step {})\n",
        superseded.size(), state_.step);
  }
  open_run_file_to_resume();
  if (file_->series_rows() != progress_.series_rows || file_->snapshot_count() != progress_.snapshots) {
    throw CheckpointError(fmt::format(
        "{}: has {} series rows and {} snapshots up to step {}, the checkpoint expects {} and {}: the run file "
        "does not belong to this checkpoint",
        summary_.run_file.string(), file_->series_rows(), file_->snapshot_count(), state_.step, progress_.series_rows,
        progress_.snapshots));
  }
}

/// Reopens run.h5 cut back to the checkpoint's step. The checkpoint holds everything the run
/// needs; run.h5 only holds its history. A run file damaged by a failed write (disk full) or a
/// crash during a flush, or deleted, must not block the run: it is moved aside and the series
/// goes on in a new run.h5 that starts at the checkpoint (a snapshot of its state, then a row per
/// step after it).
void RunSession::open_run_file_to_resume() {
  std::string unusable;  // why run.h5 cannot be reopened ("" when it can)
  if (!fs::exists(summary_.run_file)) {
    unusable = "it is missing";
  } else {
    try {
      file_.emplace(RunFile::reopen(summary_.run_file, state_.step, stage_names_));
    } catch (const std::runtime_error& error) {
      file_.reset();
      unusable = short_reason(error.what());
    }
  }
  if (unusable.empty()) return;
  fs::path aside;
  if (fs::exists(summary_.run_file)) {
    aside = directory_ / fmt::format("run.h5.damaged-at-step-{}", state_.step);
    std::error_code ignored;
    fs::rename(summary_.run_file, aside, ignored);
  }
  const std::vector<RunParameter> parameters = run_parameters(scene_, progress_.snapshot_period);
  output([&] {
    file_.emplace(RunFile::create(summary_.run_file, scene_.model, control_.scene_text, stage_names_, parameters));
  });
  first_snapshot_pending_ = true;
  progress_.series_rows = 0;
  progress_.snapshots = 0;
  if (control_.warnings) {
    *control_.warnings << fmt::format(
        "rubble run: warning: {} cannot be reopened ({}){}; the series goes on in a new {} from step {} (its "
        "first snapshot is the checkpoint's state)\n",
        summary_.run_file.string(), unusable, aside.empty() ? "" : "; moved to " + aside.string(),
        summary_.run_file.string(), state_.step);
  }
}

/// until = "rest" (run_control.hpp): stop once the grains' speeds, Z and contacts held still long
/// enough. A resumed run takes the watcher's memory from the checkpoint.
void RunSession::start_rest_watch() {
  rest_.criterion = run_.rest;
  rest_.armed = control_.rest_armed || rest_starts_armed(model_, state_);
  if (control_.resume == nullptr) return;
  restore_rest_watch(control_.resume->rest, rest_);
  // A run that ended at rest, resumed to go on (--end-time), would stop again at its first step:
  // its quiet window already lasted the duration. So would one whose thresholds were changed.
  // The window starts afresh at the next step: rest must hold for a whole duration again.
  const bool ended_at_rest = rest_.window_start && state_.time - *rest_.window_start >= rest_.criterion.duration;
  if (ended_at_rest || control_.rest_overridden) rest_.window_start.reset();
  if (ended_at_rest && run_.until_rest && control_.progress) {
    *control_.progress << "rubble run: the checkpoint's run had ended at rest; the rest watcher starts a new "
                          "window (with --until end_time the run goes on to its end time)\n";
  }
  if (control_.rest_overridden) {
    output([&] { file_->set_parameters(run_parameters(scene_, progress_.snapshot_period)); });
  }
}

/// A snapshot of the current state to the run file and the VTK series.
void RunSession::write_snapshot(bool interrupted) {
  output([&] {
    if (scene_.inflow.active()) {
      // Every body of the model, those not in play yet as NaN, and the inflow's counts.
      const auto placed = static_cast<std::int64_t>(model_.body_count() - scene_.inflow.first_body);
      const std::array<std::pair<std::string_view, std::int64_t>, 3> counts{
          {{"bodies_in_play", static_cast<std::int64_t>(model_.body_count())},
           {"inflow_placed", placed},
           {"inflow_waiting", static_cast<std::int64_t>(inflow_waiting_)}}};
      file_->write_snapshot(state_with_waiting_bodies(state_, scene_.model.body_count()), workspace_.carry.contacts,
                            interrupted, counts);
    } else {
      file_->write_snapshot(state_, workspace_.carry.contacts, interrupted);
    }
    if (vtk_) vtk_->write(state_, workspace_.carry.contacts);
  });
}

/// The inflow grains due by now enter before the step (simulation/inflow.hpp). A grain that
/// finds no room waits (and those due after it); the progress says so when it starts waiting.
void RunSession::insert_inflow_grains() {
  if (!scene_.inflow.active() || inflow_complete()) return;
  const std::size_t waiting_before = inflow_waiting_;
  const InflowInsertion insertion = insert_due_grains(scene_.inflow, scene_.model, in_play_, state_);
  grain_count_ += insertion.placed;
  inflow_waiting_ = insertion.waiting;
  if (insertion.waiting > 0 && waiting_before == 0 && control_.progress) {
    const InflowGrain& grain = scene_.inflow.grains[insertion.blocked_body - scene_.inflow.first_body];
    const Inflow& inflow = scene_.inflow.inflows[static_cast<std::size_t>(grain.inflow)];
    *control_.progress << fmt::format(
        "rubble run: inflow[{}]: step {} (t = {:.6g} s): no room for grain {} (body {}) after {} random positions "
        "in its region; {} due grain(s) wait for room (run.h5 snapshots: @inflow_waiting)\n",
        grain.inflow, state_.step, state_.time, grain.ordinal, insertion.blocked_body, inflow.attempts,
        insertion.waiting);
  }
}

void RunSession::write_checkpoint_now() {
  file_->flush();  // the run file first: the checkpoint then never promises rows that are not on disk
  progress_.series_rows = file_->series_rows();
  progress_.snapshots = file_->snapshot_count();
  // Saved from the run's own objects through a view and streamed to the file: no copy of the
  // state, contacts or detection memory, so a checkpoint adds ~1 MiB to the run's working set.
  const RestWatch saved_rest = save_rest_watch(rest_);
  const CheckpointView checkpoint{
      control_.scene_text, control_.scene_source, run_.end_time, run_.seed, state_, workspace_.carry, progress_,
      saved_rest};
  summary_.last_checkpoint =
      write_checkpoint(checkpoints_, checkpoint, control_.checkpoints_kept, run_.output.keep_checkpoint_every);
  last_checkpoint_step_ = state_.step;
}

RunSummary RunSession::run() {
  for (std::size_t b = 0; b < model_.body_count(); ++b) grain_count_ += model_.is_grain(b) ? 1 : 0;
  start_time_ = state_.time;
  start_ = Clock::now();
  last_progress_ = start_;
  last_checkpoint_time_ = start_;
  if (first_snapshot_pending_) write_snapshot(false);
  alert_distance_ = resolve_alert_distance(model_, step_options_.detection);
  while (state_.step < progress_.end_step) {
    if (!step_and_record()) break;
  }
  return finish();
}

/// One step and what follows it: the series row, the rest watch, a snapshot, a checkpoint and a
/// progress line when due. Returns false when the run must stop (a stop request, or at rest).
bool RunSession::step_and_record() {
  insert_inflow_grains();
  const auto step_start = Clock::now();
  const StepReport report = take_step();
  const auto step_end = Clock::now();
  const double step_seconds = seconds_between(step_start, step_end);

  const SeriesRow row = series_row(model_, state_, report, run_.step.gravity, step_seconds, potential_);
  warn_tunnelling();
  output([&] { file_->append_series(row); });
  account(report, step_seconds);
  const std::int64_t done = state_.step - progress_.first_step;
  // A pour is not at rest before its last grain is in: the watcher starts after it.
  const bool at_rest = run_.until_rest && grain_count_ > 0 && inflow_complete() &&
                       rest_.update(rest_sample(model_, state_, workspace_.carry.contacts, run_.rest.quantile));
  const bool at_end = state_.step == progress_.end_step || at_rest;
  if (done % progress_.snapshot_period == 0 || at_end) write_snapshot(false);

  const bool stop = control_.stop_requested != nullptr && control_.stop_requested->load(std::memory_order_relaxed) != 0;
  checkpoint_if_due(done, step_end, stop || at_end);
  // The state at a stop by signal, as the run file's last snapshot (marked @interrupted), after
  // the checkpoint: the checkpoint does not count it, and a resumed run removes it
  // (RunFile::reopen), so that its run file equals an uninterrupted run's.
  if (stop && file_->last_snapshot_step() != state_.step) write_snapshot(true);

  const auto now = Clock::now();
  summary_.output_seconds += seconds_between(step_end, now);
  if (control_.progress && (seconds_between(last_progress_, now) >= run_.output.progress_interval || at_end || stop)) {
    print_progress(report, row, now, at_rest);
  }
  if (stop) {
    summary_.interrupted = true;
    return false;
  }
  if (at_rest) {
    summary_.reached_rest = true;
    if (control_.progress) *control_.progress << "rubble run: " << rest_reason(rest_, state_.time) << "\n";
    return false;
  }
  return true;
}

/// step() with the end-of-step check: a non-finite or runaway state stops the run.
StepReport RunSession::take_step() {
  before_ = state_;
  StepReport report;
  std::optional<Problem> problem;
  try {
    report = step(model_, state_, workspace_, step_options_);
  } catch (const std::runtime_error&) {
    // A non-finite velocity makes the midpoint configuration non-finite, and detection refuses
    // it before the end-of-step check below: report it as that check would.
    problem = check_state(model_, state_, h_, control_.max_speed);
    if (!problem) throw;
  }
#if defined(__GLIBC__)
  // Every 64 steps the heap's free pages go back to the system. While a run's contact list
  // grows it lives in the heap, until glibc gives blocks over 32 MiB their own mappings; the heap
  // space it leaves behind is never trimmed (glibc's trim threshold has grown with it) and stayed
  // resident: 50 MB, a fifth of the peak at 1e5 spheres (bench/RESULTS.md, "Memory per grain").
  // The step's temporaries take their pages back once after each trim, so it costs nothing
  // measurable; results do not depend on it. The `rubble` executable also fixes the trim threshold
  // (apps/main.cpp), which returns the heap's top as it is freed; this trim is what a host that
  // keeps glibc's defaults (the Python module) gets, and it also frees pages inside the heap.
  if (state_.step % 64 == 0) malloc_trim(0);
#endif
  if (!problem) problem = check_state(model_, state_, h_, control_.max_speed);
  if (problem) fail_numerically(std::move(*problem));
  return report;
}

/// Names the step, body and first bad stage in the run file's status and a NumericalFailure.
void RunSession::fail_numerically(Problem problem) {
  const std::string stage = locate_failure(model_, before_, workspace_, step_options_, control_.max_speed, problem);
  try {
    file_->set_status(RunStatus::numerical_failure,
                      fmt::format("numerical failure at step {} (t = {:.6g} s): body {}: {}", state_.step, state_.time,
                                  problem.body, problem.what));
    file_->flush();  // what the run wrote up to the failure, if the disk takes it
  } catch (const std::runtime_error&) {
    // The numerical failure is the news; a run file that cannot be flushed is secondary.
  }
  throw NumericalFailure(
      fmt::format("step {} (t = {:.6g} s), stage {}: body {}: {}. The run stopped; the last checkpoint ({}) is intact.",
                  state_.step, state_.time, stage, problem.body, problem.what,
                  last_checkpoint_step_ >= 0 ? fmt::format("step {}", last_checkpoint_step_) : std::string("none")));
}

/// A grain that moves further than the alert distance in one step can cross a wall or another
/// grain between two detections (tunnelling): warned once, with the step and the body.
void RunSession::warn_tunnelling() {
  if (tunnelling_warned_ || !control_.progress) return;
  for (std::size_t b = 0; b < model_.body_count(); ++b) {
    if (model_.is_fixed(b)) continue;
    const double travel = h_ * state_.velocity[b].norm();
    if (travel > alert_distance_) {
      *control_.progress << fmt::format(
          "warning: step {} (t = {:.6g} s): body {} moved {:.3g} m in one step, more than the alert distance "
          "{:.3g} m; it may pass through walls or grains undetected: lower [time] dt or raise "
          "[detection] alert_distance\n",
          state_.step, state_.time, b, travel, alert_distance_);
      tunnelling_warned_ = true;
      return;
    }
  }
}

/// Steps whose solve stopped at max_iterations have contact forces less accurate than the
/// tolerance asks. A few are harmless; when at least half of a window of 100 steps are, the
/// solver is not keeping up with the scene (a deposit that keeps moving, a cap set too low), and
/// the user is told once, on the warnings stream (also in a quiet run); the summary counts them all.
void RunSession::watch_sweep_cap(const StepReport& report) {
  constexpr int window = 100;
  if (!report.solver.converged) {
    ++sweep_cap_.capped;
    sweep_cap_.largest_residual = std::max(sweep_cap_.largest_residual, report.solver.residual);
  }
  if (++sweep_cap_.steps < window) return;
  if (!sweep_cap_.warned && 2 * sweep_cap_.capped >= window && control_.warnings) {
    const SolverOptions& solver = run_.step.solver;
    *control_.warnings << fmt::format(
        "rubble run: warning: step {} (t = {:.6g} s): {} of the last {} steps stopped at the sweep cap ([solver] "
        "max_iterations = {}) short of the tolerance {:.3g} (residual up to {:.2e}): their contact forces are "
        "less accurate than asked. Raise max_iterations, or see nlgs_solver/README.md, \"Convergence criterion\" "
        "(said once; the summary counts every such step)\n",
        state_.step, state_.time, sweep_cap_.capped, window, solver.max_iterations, solver.tolerance,
        sweep_cap_.largest_residual);
    control_.warnings->flush();
    sweep_cap_.warned = true;
  }
  sweep_cap_ = SweepCapWindow{.warned = sweep_cap_.warned};
}

/// The step's share of the summary and of the run's bookkeeping (saved by checkpoints).
void RunSession::account(const StepReport& report, double step_seconds) {
  for (std::size_t s = 0; s < summary_.stage_seconds.size(); ++s) summary_.stage_seconds[s] += report.stage_seconds[s];
  summary_.polish_attempts += report.solver.polish_attempts;
  progress_.iteration_sum += report.solver.iterations;
  progress_.max_residual = std::max(progress_.max_residual, report.solver.residual);
  if (!report.solver.converged) ++progress_.unconverged_steps;
  progress_.wall_seconds += step_seconds;
  watch_sweep_cap(report);
}

/// A checkpoint every checkpoint_every_steps steps, every checkpoint_interval seconds of wall
/// time, and when `forced` (a stop request, the end).
void RunSession::checkpoint_if_due(std::int64_t done, Clock::time_point step_end, bool forced) {
  const bool by_steps = control_.checkpoint_every_steps > 0 && done % control_.checkpoint_every_steps == 0;
  const bool by_time = control_.checkpoint_interval > 0.0 &&
                       seconds_between(last_checkpoint_time_, step_end) >= control_.checkpoint_interval;
  if (forced || by_steps || by_time) {
    output([&] { write_checkpoint_now(); });
    last_checkpoint_time_ = Clock::now();
  }
}

void RunSession::print_progress(const StepReport& report, const SeriesRow& row, Clock::time_point now, bool at_rest) {
  const double elapsed = seconds_between(start_, now);
  const auto session_steps = static_cast<double>(state_.step - summary_.first_step);
  double eta = elapsed / session_steps * static_cast<double>(progress_.end_step - state_.step);
  std::string eta_text = format_duration(eta);
  if (run_.until_rest) {
    // The end is the rest time, estimated from the energy's decay; the end time caps it.
    const std::optional<double> rest_time = rest_.estimated_rest_time();
    eta = eta_seconds(elapsed, start_time_, state_.time, std::min(rest_time.value_or(run_.end_time), run_.end_time));
    eta_text =
        rest_time ? format_duration(eta) + " (to rest)" : "? (not decaying yet; at most " + format_duration(eta) + ")";
    if (at_rest) eta_text = "0s (at rest)";
  }
  // During a pour the rest watcher has not started (step_and_record): no thresholds to show yet.
  std::string rest_text;
  if (run_.until_rest)
    rest_text = inflow_complete() ? "  " + rest_progress(rest_, state_.time) : "  rest: after the inflow";
  *control_.progress << fmt::format(
      "step {:>8}/{}  t = {:.4g} s  contacts {:>6}  iterations {:>4}  residual {:.1e}  Ek {:.3e} J{}{}  elapsed {}  "
      "ETA {}\n",
      state_.step, progress_.end_step, state_.time, report.contacts, report.solver.iterations, report.solver.residual,
      row.kinetic_energy, inflow_progress(), rest_text, format_duration(elapsed), eta_text);
  control_.progress->flush();
  last_progress_ = now;
}

/// "  inflow P/T grains (W waiting)" for a run with an inflow, else nothing.
std::string RunSession::inflow_progress() const {
  if (!scene_.inflow.active()) return {};
  return fmt::format("  inflow {}/{} grains{}", model_.body_count() - scene_.inflow.first_body,
                     scene_.inflow.grains.size(),
                     inflow_waiting_ > 0 ? fmt::format(" ({} waiting)", inflow_waiting_) : std::string());
}

/// Which criterion ended the run, in words (/run@stop_reason, docs/output-format.md).
std::string RunSession::stop_reason() const {
  std::string reason = stop_reason_before_inflow();
  if (scene_.inflow.active() && !inflow_complete()) {
    reason += fmt::format("; inflow: {} of {} grains inserted, {} due and waiting for room",
                          model_.body_count() - scene_.inflow.first_body, scene_.inflow.grains.size(), inflow_waiting_);
  }
  return reason;
}

/// Which criterion ended the run, before an inflow's note.
std::string RunSession::stop_reason_before_inflow() const {
  if (summary_.interrupted) {
    return fmt::format("stopped by a signal at step {} (t = {:.6g} s)", state_.step, state_.time);
  }
  if (summary_.reached_rest) return rest_reason(rest_, state_.time);
  std::string reason = fmt::format("end time reached at t = {:.6g} s (step {})", state_.time, state_.step);
  if (run_.until_rest) {
    reason += "; not at rest: " +
              (rest_.window_start ? fmt::format("quiet for {:.4g} s of {:.4g} s", state_.time - *rest_.window_start,
                                                run_.rest.duration)
                                  : std::string("speed above the rest speed")) +
              fmt::format(" (last failed condition: {})", rest_condition_name(rest_.last_failure));
  }
  return reason;
}

/// The last checkpoint (unless this step's is written), the run file's status, and the summary.
RunSummary RunSession::finish() {
  if (last_checkpoint_step_ != state_.step) output([&] { write_checkpoint_now(); });  // e.g. a run of zero steps
  const RunStatus status = summary_.interrupted    ? RunStatus::interrupted
                           : summary_.reached_rest ? RunStatus::at_rest
                                                   : RunStatus::end_time;
  summary_.stop_reason = stop_reason();
  output([&] {
    file_->set_status(status, summary_.stop_reason);
    file_->flush();
  });
  summary_.final_step = state_.step;
  summary_.steps = state_.step - summary_.first_step;
  summary_.simulated_time = state_.time;
  summary_.wall_seconds = seconds_between(start_, Clock::now());
  const std::int64_t run_steps = state_.step - progress_.first_step;
  summary_.mean_iterations = run_steps > 0 ? progress_.iteration_sum / static_cast<double>(run_steps) : 0.0;
  summary_.max_residual = progress_.max_residual;
  summary_.unconverged_steps = progress_.unconverged_steps;
  summary_.snapshots = file_->snapshot_count();
  summary_.state_hash = state_hash(state_);
  return summary_;
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
  return run_scene(scene, std::move(initial_state), ContactList(), control);
}

RunSummary run_scene(const Scene& scene, State initial_state, ContactList warm_start, const RunControl& control) {
  // Grains of infinite or zero mass are bad input, reported before the output folder is touched.
  check_mass_properties(scene.model);
  RunSession session(scene, std::move(initial_state), std::move(warm_start), control);
  return session.run();
}

}  // namespace rubble
