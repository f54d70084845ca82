#pragma once
// `rubble post`: from a run file to metrics (CSV + HDF5), ParaView files and PNG plots, and from
// several runs to the study's comparison plots (the LMGC90 accretion paper figures 3-4). Every file written is listed
// in docs/postprocessing.md.
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "postprocessing/metrics.hpp"

namespace rubble {

class RunReader;

/// A run file whose content, or a metric computed from it, is not finite (NaN or infinite
/// positions, energies, metrics): a numerical failure, which `rubble post` reports with exit code 3
/// instead of writing NaN into its tables. what() names the file, the snapshot or series row, the
/// body or metric, and the value.
struct NonFiniteResult : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// An output file of `rubble post` could not be written (disk full, I/O error, no permission):
/// `rubble post` reports it with exit code 4. what() names the file and the reason.
struct PostOutputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Which figures fit a run: those of an aggregate (a self-gravitating pile: its diameter D_max,
/// packing fraction within it, inner sphere) or those of a deposit (grains in walls under a
/// uniform field: no aggregate diameter or packing fraction).
enum class SceneKind { aggregate, deposit };

/// How the PNGs are drawn: postprocessing/plots.py run by a Python interpreter with matplotlib.
struct PlotOptions {
  /// The interpreter. Empty: $RUBBLE_PYTHON if set, else the first of `python3` (found on PATH)
  /// and /usr/bin/python3 that imports matplotlib.
  std::string python;
  /// The script. Empty: plots_script().
  std::filesystem::path script;
};

/// What post_process_run does.
struct PostOptions {
  std::filesystem::path output_directory;  ///< where everything goes (created if missing)
  PotentialSettings potential{};           ///< the run's gravity, for the potential energy
  double time_step = 0.0;                  ///< h for forces = impulse / h (0: estimated from the series)
  int every = 1;                           ///< use every n-th snapshot (>= 1); the last one always
  bool write_vtk = false;                  ///< also write the ParaView series into OUT/vtk/
  bool plots = true;                       ///< draw the PNGs with plots.py
  PlotOptions plot{};                      ///< interpreter, script and warnings of the plots
  /// The figures drawn; unset: an aggregate for self-gravity (potential.kind), else a deposit.
  std::optional<SceneKind> scene_kind;
  int histogram_bins = 20;      ///< bins of the normal impulse distribution
  std::ostream* log = nullptr;  ///< progress and the list of files written (nullptr: silent)
  /// Notes that matter even when quiet (nullptr: nowhere): plots that cannot be drawn (no
  /// matplotlib, the script failed; the CSV and HDF5 files are written all the same and the
  /// command succeeds), a run file read while its run goes on.
  std::ostream* warnings = nullptr;
};

/// Post-processes one run file; returns the files written. Throws std::runtime_error naming the
/// file on any read/write problem, and NonFiniteResult when a series value, a snapshot's state or
/// a metric is not finite (checked before each is written). Plots that cannot be drawn (no Python
/// with matplotlib, the script failed) are a warning (PostOptions::warnings), not an error.
std::vector<std::filesystem::path> post_process_run(const std::filesystem::path& run_file, const PostOptions& options);

/// The solver settings a run was made with (its scene's [solver]), for the study's count of window
/// steps that stopped at the sweep cap.
struct SolverLimits {
  int max_iterations = 0;  ///< NLGS sweeps at most; 0: not known (no step is counted as capped)
  double tolerance = 0.0;  ///< the sweep residual asked for; 0: not known
};

/// What a study reads from each run's own scene (parsed once a run).
struct StudyRunSettings {
  /// The run's gravity, for the escape test of its last snapshot (AggregateMetrics::escaping_grains).
  PotentialSettings potential{};
  /// The run's sweep cap and tolerance, for the window's steps that stopped at the cap (their
  /// window values carry the solver's error: counted in study.csv and study.txt, and warned about).
  SolverLimits solver{};
};

/// What post_process_study does.
struct StudyOptions {
  std::filesystem::path output_directory;  ///< where study.csv and the PNGs go
  /// s: snapshots at or after this time form the stabilised regime averaged over (the paper's
  /// t > 125 min). Never replaced: a run with no snapshot that late is reported at its final
  /// snapshot, flagged (study.csv reached_window = 0, averaged_over = final_snapshot) and left out
  /// of the fits and plots unless include_unfinished.
  double stable_after = 7500.0;
  bool plots = true;   ///< draw the PNGs with plots.py
  PlotOptions plot{};  ///< interpreter, script and warnings of the plots
  /// Also fit and plot runs that did not run to their end (/run@status other than at_rest and
  /// end_time: stopped by a signal or a failure, killed, still running, or "unknown" in a format 1
  /// file) or did not reach the window. They are always listed in study.csv, with
  /// their status and reached_window, and drawn as open markers.
  bool include_unfinished = false;
  /// Each run's settings from its scene; unset: no gravity (no grain counted as escaping) and
  /// no sweep cap known (no step counted as capped). `rubble post` parses the run's scene.
  std::function<StudyRunSettings(const RunReader&)> settings_of;
  std::ostream* log = nullptr;       ///< progress (nullptr: silent)
  std::ostream* warnings = nullptr;  ///< as PostOptions::warnings
};

/// Gathers run files (each argument a run file, or a folder searched recursively for *.h5 run
/// files) into the study table (study.csv, study.txt), the fits (study_fits.csv), the <E_c>(t)
/// curves (study_kinetic_energy.csv) and the paper's panels; returns the files written. Throws
/// std::runtime_error when no run file is found, or none that ended at rest or at its end time in the window (unless
/// include_unfinished); study.csv is written first all the same.
std::vector<std::filesystem::path> post_process_study(const std::vector<std::filesystem::path>& inputs,
                                                      const StudyOptions& options);

/// Path of plots.py: $RUBBLE_PLOTS_SCRIPT if set; else, beside the running program, `plots.py` or
/// `../share/rubble/plots.py` (the build tree's BUILD/share/rubble/plots.py for BUILD/apps/rubble,
/// PREFIX/share/rubble/plots.py for an installed PREFIX/bin/rubble); else the source tree's
/// postprocessing/plots.py of the build (for test programs).
std::filesystem::path plots_script();

}  // namespace rubble
