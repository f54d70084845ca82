#pragma once
// The Python module's simulation object, in plain C++ (no Python here; bind_simulation.cpp wraps
// it): a scene's model and run options, its state and the StepWorkspace carried between steps,
// stepped one step at a time by simulation/step.hpp's step(), as run_scene's loop does. So N
// calls of advance() give the state of `rubble run` after N steps, bit for bit (the same code,
// the same data, in the same order). Between two steps the caller may change velocities, fix or
// free a body, change a contact law, the time step or the solver settings.
//
// Optionally it records a run file as `rubble run` writes it (the same RunFile: model, scene text,
// one series row per step, snapshots at the scene's cadence), and it watches for rest with the
// run loop's RestDetector.
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "postprocessing/metrics.hpp"
#include "postprocessing/run_file.hpp"
#include "postprocessing/vtk_output.hpp"
#include "simulation/checkpoint.hpp"
#include "simulation/run_control.hpp"
#include "simulation/scene.hpp"

namespace rubble::python {

/// Number of timed stages of a step.
inline constexpr std::size_t stage_count = static_cast<std::size_t>(Stage::count);

/// A scene being stepped (see the file comment).
class Simulation {
 public:
  /// Starts from the scene's initial state; `scene_text` is the scene as TOML (saved in the run
  /// file and the checkpoints; the model is rebuilt from it on load), `scene_source` the name it
  /// was parsed under. Throws std::invalid_argument if a grain's mass properties are not finite
  /// and positive (as run_scene does).
  Simulation(Scene scene, std::string scene_text, std::string scene_source);

  /// Goes on from a checkpoint: the scene parsed from its text, its state, warm start, detection
  /// memory, held gravity field and at-rest watcher. `end_time` is the checkpoint's.
  static Simulation from_checkpoint(const Checkpoint& checkpoint);

  /// A copy of this simulation at its current step (model, options, state, warm start, rest
  /// watcher), not recording: the branch steps on independently, e.g. with another friction.
  Simulation branch() const;

  /// Set by the bindings while a step runs without the GIL, so that another Python thread cannot
  /// step or change the same simulation meanwhile (read and written with the GIL held only).
  bool stepping = false;

  /// One step. Throws NumericalFailure (naming step and body) on a non-finite state.
  const StepReport& advance();

  /// Steps needed from the current time to reach `time` (the run loop's rounding: ceil((T - t)/h
  /// - 1e-9), at least 0).
  std::int64_t steps_to(double time) const;

  /// True once the rest watcher says the grains are at rest (updated by advance() when
  /// watch_rest is set).
  bool at_rest() const { return at_rest_; }
  /// Watch for rest in advance() (the scene's criterion, RunOptions::rest).
  void set_watch_rest(bool watch) { watch_rest_ = watch; }

  /// Starts recording DIR/run.h5 as `rubble run` does (creates the folder; the initial snapshot
  /// is written now). The snapshot cadence is the scene's (OutputOptions), counted from now, with
  /// the end time `end_time` for the default of 100 snapshots a run.
  void record(const std::filesystem::path& directory, double end_time);
  /// Writes a snapshot of the current step into the run file (if recording and not written yet).
  void write_snapshot();
  /// Writes a snapshot now (if recording and this step's is not written yet), flushes and closes the run file.
  void close_record();
  /// Path of the run file being recorded (empty if none).
  std::filesystem::path record_path() const;

  /// Writes a checkpoint of the current step into `folder` (step-NNNNNNNNNNNN.ckpt; the newest
  /// `keep` are kept); returns its path.
  std::filesystem::path save_checkpoint(const std::filesystem::path& folder, int keep);

  /// Fixes body b (it stops and no longer moves: zero inverse mass and inertia) or frees it again.
  void set_fixed(std::size_t body, bool fixed);
  /// True if body b is fixed (walls always are).
  bool is_fixed(std::size_t body) const { return scene_.model.is_fixed(body); }
  /// Sets the contact law of the material pair (a, b); marks the scene as modified.
  void set_contact_law(int material_a, int material_b, const ContactLaw& law);
  /// Sets the time step h, s (> 0); marks the scene as modified.
  void set_time_step(double h);

  /// Every metric of `rubble post` for the current state and contacts.
  AggregateMetrics metrics(const ContactMetricsOptions& options) const;
  /// The potential-energy settings matching the scene's gravity (what `rubble post` uses).
  PotentialSettings potential_settings() const;

  /// The scene (model and options, as changed since the start).
  const Scene& scene() const { return scene_; }
  /// The solver options, writable between steps.
  SolverOptions& solver() { return scene_.run.step.solver; }
  /// The state (writable: numpy views point into its arrays).
  State& state() { return state_; }
  /// The state (read only).
  const State& state() const { return state_; }
  /// The contacts of the last step (impulses, status).
  const ContactList& contacts() const { return workspace_.carry.contacts; }
  /// The last step's report (zero before the first step).
  const StepReport& last_report() const { return last_report_; }
  /// Wall time per stage summed over the steps taken by this object, s.
  const std::array<double, stage_count>& total_stage_seconds() const { return total_stage_seconds_; }
  /// The scene text saved with checkpoints and run files.
  const std::string& scene_text() const { return scene_text_; }
  /// Grains (bodies that are not walls) in the model.
  std::size_t grain_count() const { return grain_count_; }

 private:
  Simulation() = default;
  Scene scene_;
  std::string scene_text_;
  std::string scene_source_;
  bool scene_modified_ = false;  ///< dt or a contact law changed: checkpoints save scene_to_toml(scene_)
  State state_;
  StepWorkspace workspace_;
  StepReport last_report_{};
  std::array<double, stage_count> total_stage_seconds_{};
  std::size_t grain_count_ = 0;
  /// The grains' circumscribed and equivalent diameters for metrics(): shapes never change, so
  /// they are computed at the first call (one smallest enclosing ball per polyhedron), not each.
  mutable std::optional<GrainSizes> grain_sizes_;
  std::vector<double> free_inverse_mass_;   ///< the model's inverse masses, restored when a body is freed
  std::vector<Vec3> free_inverse_inertia_;  ///< the same for the inverse inertia

  bool watch_rest_ = false;
  bool at_rest_ = false;
  RestDetector rest_{};

  std::optional<RunFile> record_;
  /// The ParaView series of the recording (DIR/vtk) when the scene says [output] vtk = true. It
  /// points to scene_.model: created by record(), when the object no longer moves (it lives in
  /// its Python wrapper).
  std::optional<VtkSeries> record_vtk_;
  std::int64_t record_first_step_ = 0;
  std::int64_t snapshot_period_ = 1;
  std::int64_t last_snapshot_step_ = -1;
  RunProgress progress_{};                  ///< bookkeeping saved with checkpoints (series rows, snapshots, sums)
  std::optional<double> potential_energy_;  ///< J, the grains' potential energy after the last recorded step
};

}  // namespace rubble::python
