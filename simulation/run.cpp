#include "simulation/run.hpp"

#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <ostream>

#include "postprocessing/metrics.hpp"
#include "postprocessing/run_file.hpp"

namespace rubble {
namespace {

using Clock = std::chrono::steady_clock;

std::string format_duration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const auto s = static_cast<long long>(seconds + 0.5);
  if (s >= 3600) return fmt::format("{}h{:02}m", s / 3600, (s % 3600) / 60);
  if (s >= 60) return fmt::format("{}m{:02}s", s / 60, s % 60);
  return fmt::format("{}s", s);
}

/// Stops the run with a clear message if any grain's state is not finite.
void check_finite(const Model& model, const State& state) {
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!state.position[b].allFinite() || !state.velocity[b].allFinite() || !state.angular_velocity[b].allFinite() ||
        !state.orientation[b].coeffs().allFinite()) {
      throw NumericalFailure(fmt::format("non-finite state at step {} (t = {:.6g} s), body {}, after the step's "
                                         "update_positions stage",
                                         state.step, state.time, b));
    }
  }
}

/// Steps between snapshots from the output options.
std::int64_t snapshot_period(const RunOptions& run, std::int64_t total_steps) {
  if (run.output.snapshot_every_steps > 0) return run.output.snapshot_every_steps;
  if (run.output.snapshot_interval > 0.0) {
    return std::max<std::int64_t>(1, std::llround(run.output.snapshot_interval / run.step.integrator.time_step));
  }
  return std::max<std::int64_t>(1, total_steps / 100);
}

}  // namespace

RunSummary run_scene(const Scene& scene, const RunControl& control) {
  const Model& model = scene.model;
  const RunOptions& run = scene.run;
  State state = scene.state;
  StepWorkspace workspace;
  RunSummary summary;

  std::filesystem::create_directories(run.output.directory);
  summary.run_file = std::filesystem::path(run.output.directory) / "run.h5";
  std::vector<std::string_view> stage_names;
  for (std::size_t s = 0; s < static_cast<std::size_t>(Stage::count); ++s) stage_names.push_back(stage_name(static_cast<Stage>(s)));
  RunFile file = RunFile::create(summary.run_file, model, control.scene_text, stage_names);

  const double h = run.step.integrator.time_step;
  const auto total_steps = static_cast<std::int64_t>(std::ceil((run.end_time - state.time) / h - 1e-9));
  const std::int64_t period = snapshot_period(run, total_steps);
  const auto start = Clock::now();
  auto last_progress = start;
  double iteration_sum = 0.0;

  file.write_snapshot(state, workspace.contacts);
  ++summary.snapshots;
  for (std::int64_t k = 0; k < total_steps; ++k) {
    const auto step_start = Clock::now();
    const StepReport report = step(model, state, workspace, run.step);
    check_finite(model, state);
    const double step_seconds = std::chrono::duration<double>(Clock::now() - step_start).count();

    SeriesRow row;
    row.step = state.step;
    row.time = state.time;
    row.kinetic_energy = kinetic_energy(model, state);
    row.contacts = static_cast<std::int64_t>(report.contacts);
    row.active_contacts = static_cast<std::int64_t>(report.solver.active_contacts);
    row.iterations = report.solver.iterations;
    row.residual = report.solver.residual;
    row.wall_seconds = step_seconds;
    row.stage_seconds = report.stage_seconds;
    file.append_series(row);

    iteration_sum += report.solver.iterations;
    summary.max_residual = std::max(summary.max_residual, report.solver.residual);
    if (!report.solver.converged) ++summary.unconverged_steps;
    if ((k + 1) % period == 0 || k + 1 == total_steps) {
      file.write_snapshot(state, workspace.contacts);
      ++summary.snapshots;
    }

    const auto now = Clock::now();
    if (control.progress && (std::chrono::duration<double>(now - last_progress).count() >= run.output.progress_interval ||
                             k + 1 == total_steps)) {
      const double elapsed = std::chrono::duration<double>(now - start).count();
      const double eta = elapsed / static_cast<double>(k + 1) * static_cast<double>(total_steps - k - 1);
      *control.progress << fmt::format(
          "step {:>8}/{}  t = {:.4g} s  contacts {:>6}  iterations {:>4}  residual {:.1e}  Ek {:.3e} J  elapsed {}  ETA {}\n",
          k + 1, total_steps, state.time, report.contacts, report.solver.iterations, report.solver.residual,
          row.kinetic_energy, format_duration(elapsed), format_duration(eta));
      control.progress->flush();
      last_progress = now;
    }
  }
  file.flush();
  summary.steps = total_steps;
  summary.simulated_time = state.time;
  summary.wall_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  summary.mean_iterations = total_steps > 0 ? iteration_sum / static_cast<double>(total_steps) : 0.0;
  return summary;
}

}  // namespace rubble
