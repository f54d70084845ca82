#pragma once
// Reading a run file back (docs/output-format.md): the model, the scene text, the per-step series
// and any snapshot, as the same Model / State / Contact types the run used. What `rubble post`
// and the metrics work from after a run.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/contact.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// The per-step series of a run file, one vector per column (all the same length).
struct RunSeries {
  std::vector<std::int64_t> step;             ///< steps taken
  std::vector<double> time;                   ///< s
  std::vector<double> kinetic_energy;         ///< J, total
  std::vector<std::int64_t> contacts;         ///< contact points found
  std::vector<std::int64_t> active_contacts;  ///< contacts in the solver's problem
  std::vector<std::int64_t> iterations;       ///< NLGS sweeps
  std::vector<double> residual;               ///< NLGS residual at exit
  std::vector<double> wall_seconds;           ///< s, wall time per step
  /// The conservation monitor's columns present in the file (potential_energy, total_energy,
  /// linear_momentum_x/y/z, angular_momentum_x/y/z; docs/output-format.md), by name; none in run
  /// files written before 2026-11-24.
  std::vector<std::string> monitor_names;
  std::vector<std::vector<double>> monitor;        ///< one column per monitor name
  std::vector<std::string> stage_names;            ///< names of the stage columns, in step order
  std::vector<std::vector<double>> stage_seconds;  ///< s, one column per stage name
};

/// A snapshot read back: the state and the contact points (id.body_a/b, point, frame, gap,
/// impulse, angular_impulse (zero unless a law resists rotation), status filled; the solver's
/// working fields left at their defaults; features 0).
struct RunSnapshot {
  State state;           ///< time, step, positions, orientations, velocities
  ContactList contacts;  ///< the contacts of the step that ended at that time
  /// Bodies in play: all of them, or in a run with [[inflow]] the snapshot's @bodies_in_play (the
  /// later bodies are inflow grains not inserted yet, NaN in `state`; model_prefix and
  /// state_prefix, core/model.hpp, give the bodies in play).
  std::size_t bodies_in_play = 0;
};

/// A run file open for reading. Every problem (not an HDF5 file, not a rubble run file, a newer
/// format version, a missing or misshapen dataset) throws std::runtime_error naming the file.
class RunReader {
 public:
  /// Opens the file and reads its model, scene text and snapshot list. A file held by a running
  /// `rubble run` (HDF5 1.10 locks a file open for writing) is opened without the lock: what the
  /// run flushed last (at its last checkpoint) is read, and live() says so.
  static RunReader open(const std::filesystem::path& path);

  RunReader(RunReader&&) noexcept;             ///< takes over the open file
  RunReader& operator=(RunReader&&) noexcept;  ///< takes over the open file
  ~RunReader();                                ///< closes the file

  /// The file's path.
  const std::filesystem::path& path() const;
  /// The model, rebuilt from /model (shapes, masses, inertia, materials, contact laws).
  const Model& model() const;
  /// The scene as TOML text (/scene).
  const std::string& scene_text() const;
  /// Number of snapshots.
  std::size_t snapshot_count() const;
  /// Reads snapshot `index` (0-based, in time order).
  RunSnapshot read_snapshot(std::size_t index) const;
  /// Reads the whole per-step series.
  RunSeries read_series() const;
  /// The time step h: /run/time_step (format version 2), else estimated from the series as
  /// (t_last - t_first) / (steps between them), or t / step from a single row; 0 if the series is
  /// empty. Turns impulses (N s) into forces (N).
  double time_step() const;
  /// Why the run ended (/run@status: "running", "at_rest", "end_time", "interrupted",
  /// "numerical_failure", "closed"; docs/output-format.md), or "unknown" for a version 1 file.
  const std::string& status() const;
  /// True when the file was open for writing by a running `rubble run` (HDF5's file lock was
  /// held): it was opened without the lock and shows the run as of its last flush.
  bool live() const;

 private:
  struct Impl;
  explicit RunReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace rubble
