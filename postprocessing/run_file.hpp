#pragma once
// The HDF5 run file: what a run writes (the model, the scene text, one row of the per-step series
// per step, state + contact snapshots) and what post-processing reads back. The layout is
// documented in docs/output-format.md; that document and run_file.cpp, run_file_datasets.cpp must
// stay in step.
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/contact.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// A contact-law parameter stored in /model/contact_laws as an (M, M) dataset, besides friction
/// and restitution (always there): the dataset, the ContactLaw member it holds, its units.
struct ContactLawField {
  const char* name;            ///< dataset name
  double ContactLaw::*member;  ///< the parameter
  const char* units;           ///< units attribute
};

/// Those parameters, written by RunFile and read back by RunReader (files written before
/// 2026-11-24 lack them: read as 0), so that a state exported from the file (rubble export) keeps
/// the contact laws it ran with.
inline constexpr std::array<ContactLawField, 5> optional_contact_law_fields{
    {{"tangential_restitution", &ContactLaw::tangential_restitution, "1"},
     {"cohesion", &ContactLaw::cohesion, "N"},
     {"work_of_adhesion", &ContactLaw::work_of_adhesion, "J/m^2"},
     {"rolling_friction", &ContactLaw::rolling_friction, "1"},
     {"twisting_friction", &ContactLaw::twisting_friction, "1"}}};

/// Identifies the layout in the file's root attributes; bump format_version on any change.
inline constexpr std::string_view run_file_format = "rubble-run";
/// Version of the layout written by RunFile (docs/output-format.md). 2: units on every numeric
/// dataset, gzip compression, /run (status and resolved settings), /snapshot_time and
/// /snapshot_step, /snapshots/NNNNNN@interrupted. RunReader reads versions 1 and 2.
inline constexpr int run_file_format_version = 2;

/// One setting of the run as the run used it (/run/<name> in the run file): what the scene gave,
/// or what rubble chose where the scene said "auto" or left the key out.
struct RunParameter {
  std::string name;        ///< dataset name under /run (no '/' or '.')
  double value = 0.0;      ///< in SI units
  std::string units;       ///< e.g. "s", "J", "m"
  bool automatic = false;  ///< chosen by rubble ("auto" or a default computed from the scene)
};

/// Why a run file's run ended, or that it has not (/run@status).
enum class RunStatus {
  running,            ///< being written, or the writer was killed (SIGKILL, power loss)
  at_rest,            ///< stopped because the grains were at rest (until = "rest")
  end_time,           ///< reached its end time
  interrupted,        ///< stopped by SIGINT/SIGTERM; the last snapshot is the state at the stop
  numerical_failure,  ///< stopped on a non-finite or runaway state
  closed,             ///< a recording closed by its program (Python Simulation) before either end
};

/// The word stored for a status ("running", "at_rest", ...).
std::string_view run_status_name(RunStatus status);

/// One row of the per-step series (/series in the run file).
struct SeriesRow {
  std::int64_t step = 0;                 ///< number of steps taken
  double time = 0.0;                     ///< s, simulated time at the end of the step
  double kinetic_energy = 0.0;           ///< J, total (translation + rotation) over all bodies
  std::int64_t contacts = 0;             ///< contact points found (gap < alert distance)
  std::int64_t active_contacts = 0;      ///< contacts in the solver's problem
  int iterations = 0;                    ///< NLGS sweeps done
  double residual = 0.0;                 ///< NLGS residual at exit
  double wall_seconds = 0.0;             ///< wall time of the whole step, s
  double potential_energy = 0.0;         ///< J, gravitational potential energy of the grains (StepReport)
  double total_energy = 0.0;             ///< J, kinetic + potential
  Vec3 linear_momentum = Vec3::Zero();   ///< kg m/s, of the grains
  Vec3 angular_momentum = Vec3::Zero();  ///< kg m^2/s, of the grains about their centre of mass
  /// Wall time of each stage, s, in the order of the stage names given to RunFile::create.
  /// A view: the caller's array must live until append_series returns (it is copied).
  std::span<const double> stage_seconds;
};

/// An open HDF5 run file being written (RAII: the file is flushed and closed on destruction).
/// Move-only. Every HDF5 failure (cannot create the file, disk full, ...) throws
/// std::runtime_error naming the file; the destructor never throws (it reports on stderr). After
/// a failed write the file is marked failed: later writes throw at once, and the destructor
/// closes the objects without flushing again (HDF5 cannot write what the disk refused).
class RunFile {
 public:
  /// Creates (truncates) the file and writes the root attributes, /scene and /model.
  /// `scene_text` is the scene as TOML, stored verbatim so that the run can be reproduced.
  /// `stage_names` names the columns of SeriesRow::stage_seconds (/series/stage_seconds/<name>);
  /// names must be non-empty, unique and free of '/' and '.'.
  /// `parameters` are stored under /run with their units and whether they were automatic; the
  /// status starts as "running".
  static RunFile create(const std::filesystem::path& path, const Model& model, std::string_view scene_text,
                        std::span<const std::string_view> stage_names, std::span<const RunParameter> parameters = {});

  /// Opens an existing run file to resume a run from a checkpoint taken at step `last_step`:
  /// series rows and snapshots of later steps (written after that checkpoint by the run that
  /// stopped) are removed, so that the resumed run appends with no step written twice or missing.
  /// `stage_names` must be the names the file was created with. Throws std::runtime_error naming
  /// the file if it cannot be opened or is not a run file. (simulation/checkpoint.hpp)
  /// A snapshot written at an interruption (write_snapshot(..., interrupted = true)) is removed
  /// too: the resumed run goes on from that state, and its file then equals an uninterrupted run's.
  /// The status goes back to "running".
  static RunFile reopen(const std::filesystem::path& path, std::int64_t last_step,
                        std::span<const std::string_view> stage_names);

  RunFile(RunFile&&) noexcept;             ///< takes over the open file
  RunFile& operator=(RunFile&&) noexcept;  ///< closes this file (flushing it), takes over the other
  RunFile(const RunFile&) = delete;
  RunFile& operator=(const RunFile&) = delete;
  ~RunFile();  ///< flushes buffered rows and closes the file; errors go to stderr

  /// Buffers one row; rows reach the file every series_buffer_rows rows and on flush().
  /// Throws std::invalid_argument if row.stage_seconds does not match the stage names.
  void append_series(const SeriesRow& row);
  /// Writes /snapshots/NNNNNN (NNNNNN = number of snapshots written before, 6 digits) with the
  /// state of every body and every contact point of the list, and a row of /snapshot_time and
  /// /snapshot_step. `interrupted` marks the state at a stop by signal (@interrupted = 1), which
  /// reopen() removes. `attributes` are more integer attributes of the snapshot (an inflow run's
  /// bodies_in_play, inflow_placed and inflow_waiting: docs/output-format.md).
  void write_snapshot(const State& state, const ContactList& contacts, bool interrupted = false,
                      std::span<const std::pair<std::string_view, std::int64_t>> attributes = {});
  /// Sets /run@status and /run@stop_reason, a sentence saying which criterion ended the run
  /// (written to disk with the next flush).
  void set_status(RunStatus status, std::string_view reason = {});
  /// Writes (or replaces) /run/<name> for each parameter: a resumed run whose settings were
  /// overridden on the command line (`rubble run --resume DIR --rest-speed V`) records them.
  void set_parameters(std::span<const RunParameter> parameters);
  /// Writes the buffered series rows and flushes HDF5's buffers to disk.
  void flush();
  /// From now on HDF5 writes the file's metadata only in flush() (and on close): its metadata
  /// cache stops evicting dirty entries in between. A process killed between two flushes then
  /// leaves a file whose metadata is that of the last flush, which reopen() can cut back to a
  /// checkpoint. Costs memory for the metadata touched between flushes (small: a few groups and
  /// index nodes). Used by the run loop, which flushes at every checkpoint.
  void hold_metadata_until_flush();

  /// The file's path.
  const std::filesystem::path& path() const;
  /// Snapshots written so far.
  std::int64_t snapshot_count() const;
  /// Series rows appended so far (written or buffered).
  std::int64_t series_rows() const;
  /// s, simulated time of every snapshot in the file, in order.
  const std::vector<double>& snapshot_times() const;
  /// Step of the last snapshot written (-1 if none).
  std::int64_t last_snapshot_step() const;

  /// Rows kept in memory between two writes of the series.
  static constexpr std::size_t series_buffer_rows = 1000;

 private:
  struct Impl;
  explicit RunFile(std::unique_ptr<Impl> impl);
  void write_snapshot_now(const State& state, const ContactList& contacts, bool interrupted,
                          std::span<const std::pair<std::string_view, std::int64_t>> attributes);
  std::unique_ptr<Impl> impl_;
};

}  // namespace rubble
