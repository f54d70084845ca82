#pragma once
// The run loop: steps a scene to its end time, prints progress, writes the run file, writes
// checkpoints and resumes from them (docs/checkpoints.md), and stops with a message on a
// numerical failure.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "postprocessing/run_file.hpp"
#include "simulation/checkpoint.hpp"
#include "simulation/scene.hpp"

namespace rubble {

/// Raised when the state becomes non-finite or runs away; names the step, the body and the
/// first stage of the step whose output was bad. The last checkpoint is left untouched.
struct NumericalFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Writing the run's output failed (disk full, I/O error, folder removed): the run stopped.
/// what() names the file, the system's reason, the step, and the last checkpoint, which is left
/// intact (a failed checkpoint write removes its temporary file), so that the run can go on with
/// `rubble run --resume DIR` once the cause is fixed.
struct OutputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// What the caller of run_scene controls besides the scene.
struct RunControl {
  std::ostream* progress = nullptr;  ///< where progress lines go (nullptr: silent)
  /// Where notes that matter even in a quiet run go (a stale lock taken over, a damaged run file
  /// set aside on resume); nullptr: nowhere.
  std::ostream* warnings = nullptr;
  std::string scene_text;    ///< the scene as TOML, stored in the run file and the checkpoints
  std::string scene_source;  ///< the name the scene was parsed under (saved for resuming)

  /// Write a checkpoint every N steps (0: not by step count).
  std::int64_t checkpoint_every_steps = 0;
  /// Write a checkpoint when this many seconds of wall time passed since the last one (0: not by
  /// wall time). Either trigger writes one; a run also writes one at its end and when stopped.
  double checkpoint_interval = 600.0;
  /// Checkpoints kept in DIR/checkpoints (the newest ones).
  int checkpoints_kept = 2;

  /// Runaway bound on a grain's speed, m/s. 0 (default): automatic, per grain: a grain may not
  /// move farther than its bounding radius in one step (|v| h <= bounding radius), beyond which
  /// contact detection can miss contacts altogether. A negative value disables the check.
  double max_speed = 0.0;

  /// Set asynchronously (by a SIGINT/SIGTERM handler, to the signal's number) to ask the run to
  /// stop: nonzero makes it finish the current step, write a checkpoint and return with
  /// RunSummary::interrupted. May be nullptr.
  const std::atomic<int>* stop_requested = nullptr;

  /// Resume from this checkpoint instead of the scene's initial state (nullptr: a new run). The
  /// scene must be the checkpoint's (parsed from its scene_text); run.end_time may differ from
  /// the checkpoint's to extend or shorten the run. The run file DIR/run.h5 is reopened and cut
  /// back to the checkpoint's step; when it is missing or cannot be reopened (damaged), it is
  /// moved to DIR/run.h5.damaged-at-step-K and the series goes on in a new DIR/run.h5 whose first
  /// snapshot is the checkpoint's state (a note goes to `warnings`).
  const Checkpoint* resume = nullptr;
  /// With `resume`: the scene's rest settings were changed (rubble run --resume DIR --rest-speed
  /// ...): the watcher's quiet window starts afresh and /run records the new thresholds.
  bool rest_overridden = false;
  /// The rest watcher starts armed: a run branched from another's state (rubble run SCENE --from
  /// DIR) may start quiet, and must still stop at rest (a new run arms on the first motion).
  bool rest_armed = false;
};

/// What a run did.
struct RunSummary {
  std::int64_t first_step = 0;            ///< state.step when this session started (> 0 when resumed)
  std::int64_t steps = 0;                 ///< steps taken in this session
  std::int64_t final_step = 0;            ///< state.step at the end
  double simulated_time = 0.0;            ///< s
  double wall_seconds = 0.0;              ///< s, this session
  double mean_iterations = 0.0;           ///< NLGS sweeps per step, over the whole run
  double max_residual = 0.0;              ///< largest end-of-step residual, over the whole run
  std::int64_t unconverged_steps = 0;     ///< steps that hit max_iterations, over the whole run
  std::int64_t snapshots = 0;             ///< snapshots in the run file
  std::filesystem::path run_file;         ///< the HDF5 file written
  bool interrupted = false;               ///< stopped by RunControl::stop_requested before the end
  bool reached_rest = false;              ///< stopped because the grains were at rest (until = "rest")
  std::string stop_reason;                ///< which criterion ended the run, in words (/run@stop_reason)
  std::filesystem::path last_checkpoint;  ///< the checkpoint written last (empty if none)
  std::uint64_t state_hash = 0;           ///< state_hash() of the final state
  /// s of wall time per stage of the step (Stage order), summed over this session's steps.
  std::array<double, static_cast<std::size_t>(Stage::count)> stage_seconds{};
  double output_seconds = 0.0;       ///< s of wall time writing series, snapshots and checkpoints
  std::int64_t polish_attempts = 0;  ///< Newton polishes of the contact problem (SolverOptions::polish_after)
};

/// The series row of a step that just ended in `state` (run.h5 /series, docs/output-format.md),
/// with the conservation monitor: `potential` carries the grains' potential energy from step to
/// step (a step that held the self-gravity field reports only the held forces' work; with no
/// previous value the energy is evaluated afresh at `state`, which changes nothing in the run).
/// stage_seconds views report.stage_seconds.
SeriesRow series_row(const Model& model, const State& state, const StepReport& report, const GravitySettings& gravity,
                     double wall_seconds, std::optional<double>& potential);

/// The settings stored under /run in the run file (docs/output-format.md): the time step, alert
/// distance, pair-list margin and snapshot period (steps) as the run uses them, and with
/// until = "rest" the rest threshold and duration; each says whether rubble chose it ("auto", or
/// a key left out whose default depends on the scene).
std::vector<RunParameter> run_parameters(const Scene& scene, std::int64_t snapshot_period);

/// Runs `scene` from its initial state (or from control.resume) to its end time. Writes
/// DIR/run.h5 (model, per-step series, snapshots; docs/output-format.md) and checkpoints in
/// DIR/checkpoints (docs/checkpoints.md), DIR = scene.run.output.directory, which it locks
/// first (simulation/output_lock.hpp: OutputFolderBusy if another process runs there,
/// OutputFolderError if it cannot be made; nothing is opened before). Throws
/// NumericalFailure on a non-finite or runaway state, OutputError when writing the run file or a
/// checkpoint fails (std::runtime_error on other I/O errors),
/// CheckpointError if control.resume does not fit the scene or the run file, and
/// std::invalid_argument (before writing anything) if a grain's mass, inertia or size is not
/// finite and positive.
RunSummary run_scene(const Scene& scene, const RunControl& control);

/// The same, running from `initial_state` instead of a copy of scene.state (which is not read):
/// a caller that moves the scene's state in keeps one copy of it instead of two during the run
/// (104 bytes a body).
RunSummary run_scene(const Scene& scene, State initial_state, const RunControl& control);

/// The same, with `warm_start` as the first step's warm start (a branch's saved contacts,
/// branch_warm_start in branch.hpp; empty: from zero impulses), moved into the run's own contact
/// list so that no second copy lives during the run. Not used when resuming (the checkpoint has
/// its own).
RunSummary run_scene(const Scene& scene, State initial_state, ContactList warm_start, const RunControl& control);

}  // namespace rubble
