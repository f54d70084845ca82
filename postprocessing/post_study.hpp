#pragma once
// post_process_study's steps: each run file reduced to a StudyRun (post_study_runs.cpp), then the
// tables written from them (post_study_tables.cpp). Internal to postprocessing/post_study*.cpp;
// post.hpp is the public API, docs/postprocessing.md describes the files written.
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "postprocessing/metrics.hpp"
#include "postprocessing/post.hpp"

namespace rubble::post_detail {

/// Mean and standard deviation (n - 1 in the denominator; 0 for one value).
struct Spread {
  double mean = 0.0;       ///< arithmetic mean (NaN for no value)
  double deviation = 0.0;  ///< sample standard deviation (NaN for no value)
};

/// The Spread of `values`.
Spread spread(const std::vector<double>& values);

/// x with 4 significant digits (the study table: a window mean is not known to 17 digits), in
/// fixed notation between 1e-3 and 1e6 so that times and counts read plainly; empty for NaN (a
/// quantity that does not apply, such as the rest time of a run not at rest).
std::string significant(double x);

/// A parameter of the run (mu, the window's start) as given: 0.4, not 0.4000.
std::string parameter_text(double x);

/// A count (grains, snapshots) as an integer.
std::string count_text(double x);

/// A metric averaged over the window: its study.csv column name and how it is read from a snapshot's metrics.
using AveragedMetric = std::pair<std::string, double (*)(const AggregateMetrics&)>;

/// The metrics averaged over the window, in study.csv's column order.
std::vector<AveragedMetric> averaged_metrics();

/// One run of a study, reduced to the quantities of the study table.
struct StudyRun {
  std::string path;                      ///< the run file
  std::string status;                    ///< /run@status ("unknown" in a format 1 file)
  std::string shape;                     ///< "spheres", "polyhedra" or "mixed"
  std::string averaged_over;             ///< "window", or "final_snapshot" when the run did not reach it
  bool at_rest = false;                  ///< status is at_rest
  bool reached_window = false;           ///< a snapshot at t >= stable_after exists
  bool included = false;                 ///< in the fits and plots
  double grains = 0.0;                   ///< n_s
  double friction = 0.0;                 ///< mu, the mean over the grains' material pairs
  double end_time = 0.0;                 ///< s, of the last snapshot
  std::size_t snapshots_used = 0;        ///< snapshots averaged over
  double peak_time = 0.0;                ///< s, of the peak of <E_c>(t)
  double peak_energy = 0.0;              ///< J, the peak of <E_c>(t)
  double rest_time = std::nan("");       ///< s, the series' last time when the run ended at rest
  double plateau = std::nan("");         ///< J, mean <E_c> over the window
  std::map<std::string, Spread> values;  ///< window mean and spread of each averaged metric
  double max_overlap = 0.0;              ///< m, deepest overlap over the window
  double detached = 0.0;                 ///< detached grains at the last snapshot
  double escaping = 0.0;                 ///< escaping grains at the last snapshot
  SolverLimits solver{};                 ///< the run's sweep cap and tolerance (0: not known)
  std::size_t window_steps = 0;          ///< steps of the series in the window
  std::size_t capped_steps = 0;          ///< of them, those that stopped at the sweep cap
  double max_residual = std::nan("");    ///< the largest sweep residual at a step's end in the window
  std::vector<double> energy_time;       ///< s, <E_c>(t) thinned for the plot: times
  std::vector<double> energy;            ///< J, <E_c>(t) thinned for the plot: values
};

/// The runs of a study and those left out of its fits and plots, each with the reason.
struct StudyRuns {
  std::vector<StudyRun> runs;         ///< every run file with snapshots, sorted for the table
  std::vector<std::string> left_out;  ///< "PATH (why)" of the runs not included
};

/// The run files named by `inputs` (files, or folders searched recursively for *.h5), sorted.
/// Throws std::runtime_error for an input that does not exist.
std::vector<std::filesystem::path> collect_run_files(const std::vector<std::filesystem::path>& inputs);

/// Each run file reduced to a StudyRun (files that are no run file or hold no snapshot skipped),
/// sorted by shape, mu, n_s and path.
StudyRuns reduce_runs(const std::vector<std::filesystem::path>& runs, const StudyOptions& options);

/// study.csv: every run, flagged or not; returns its path.
std::filesystem::path write_study_csv(const std::filesystem::path& out, const std::vector<StudyRun>& study,
                                      const StudyOptions& options);

/// study_fits.csv: power-law (and, for the peak energy, exponential) fits per (shape, mu) series
/// of the included runs; returns its path.
std::filesystem::path write_study_fits(const std::filesystem::path& out, const std::vector<StudyRun>& study);

/// study_means.csv: per parameter set (shape, mu, n_s) of the included runs, the number of runs
/// (seeds) and the mean and standard deviation over them of each run's window means, peak and
/// plateau; returns its path.
std::filesystem::path write_study_means(const std::filesystem::path& out, const std::vector<StudyRun>& study);

/// study_kinetic_energy.csv: the thinned <E_c>(t) curve of every run; returns its path.
std::filesystem::path write_study_kinetic_energy(const std::filesystem::path& out, const std::vector<StudyRun>& study);

/// study.txt: the table a reader compares with the paper, aligned, at 4 significant digits (also
/// copied to the log); returns its path.
std::filesystem::path write_study_text(const std::filesystem::path& out, const std::vector<StudyRun>& study,
                                       const StudyOptions& options);

}  // namespace rubble::post_detail
