#pragma once
// What post_process_run (post_run.cpp) and post_process_study (post_study*.cpp) share: the CSV
// writer, the output folder, the finiteness checks and the call of plots.py (post.cpp). Internal
// to postprocessing/post*.cpp; post.hpp is the public API.
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <iosfwd>
#include <string>
#include <vector>

#include "postprocessing/post.hpp"
#include "postprocessing/run_reader.hpp"

namespace rubble::post_detail {

/// A CSV file written row by row; numbers in the shortest form that reads back exactly. Failures
/// throw PostOutputError naming the file.
class CsvWriter {
 public:
  /// Creates the file and writes the header line.
  CsvWriter(const std::filesystem::path& path, const std::vector<std::string>& header);
  /// Writes a row of numbers (%.17g: they read back exactly).
  void row(const std::vector<double>& values);
  /// Writes a row of texts as they are.
  void text_row(const std::vector<std::string>& values);
  /// Closes the file; throws if anything could not be written.
  void close();

 private:
  std::filesystem::path path_;
  std::ofstream out_;
};

/// x in the shortest form that reads back exactly (%.17g).
std::string number(double x);

/// Creates the output folder (and its parents); throws PostOutputError naming it when it cannot.
void create_output_directory(const std::filesystem::path& directory);

/// Draws the PNGs of `mode` ("run" or "study") with plots.py; returns false, with a warning, when
/// it cannot (the CSV files are there all the same: plots are a convenience, not the result).
bool run_plots(const std::string& mode, const std::string& arguments, const std::filesystem::path& directory,
               const PlotOptions& options, std::ostream* log, std::ostream* warnings);

/// Appends to `written` each of the PNGs `names` that plots.py wrote into `directory`, and warns
/// (if `warnings`) for each it did not write.
void add_plot_files(const std::filesystem::path& directory, const std::vector<std::string>& names,
                    std::vector<std::filesystem::path>& written, std::ostream* warnings);

/// Throws NonFiniteResult when a series row holds a non-finite time, energy or residual.
void check_series(const std::filesystem::path& run_file, const RunSeries& series);

/// Throws NonFiniteResult when a body of the snapshot has a non-finite position, orientation or
/// velocity: every metric of it would be NaN.
void check_snapshot(const std::filesystem::path& run_file, std::size_t index, const State& state);

/// Throws NonFiniteResult naming the first non-finite metric of a snapshot's row.
void check_metrics(const std::filesystem::path& run_file, std::size_t index, const std::vector<double>& row);

}  // namespace rubble::post_detail
