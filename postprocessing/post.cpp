// What post_process_run (post_run.cpp) and post_process_study (post_study_*.cpp) share, declared
// in post_detail.hpp: the CSV writer, the output folder, the finiteness checks, running plots.py;
// and plots_script(), where plots.py is found.
#include "postprocessing/post.hpp"

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <ostream>
#include <stdexcept>

#include "postprocessing/post_detail.hpp"

#ifndef RUBBLE_PLOTS_SCRIPT
#define RUBBLE_PLOTS_SCRIPT "postprocessing/plots.py"
#endif

namespace rubble {
namespace post_detail {
namespace {

namespace fs = std::filesystem;

std::string shell_quote(const std::string& text) {
  std::string quoted = "'";
  for (char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

/// True if `python` runs and imports matplotlib (its output is discarded).
bool has_matplotlib(const std::string& python) {
  const std::string command = shell_quote(python) + " -c 'import matplotlib' > /dev/null 2>&1";
  return std::system(command.c_str()) == 0;
}

/// The interpreter that draws the plots (PlotOptions::python), or nullopt with the reason.
std::optional<std::string> plotting_python(const PlotOptions& options, std::string& reason) {
  std::vector<std::string> candidates;
  if (!options.python.empty()) {
    candidates = {options.python};
  } else if (const char* requested = std::getenv("RUBBLE_PYTHON"); requested != nullptr && *requested != '\0') {
    candidates = {requested};
  } else {
    // `python3` on PATH first (a virtual environment, a conda or pyenv interpreter); the system's
    // own next, which has matplotlib on Debian once python3-matplotlib is installed, when the one
    // on PATH has not (scripts/install-deps.sh installs it).
    candidates = {"python3", "/usr/bin/python3"};
  }
  for (const std::string& python : candidates) {
    if (has_matplotlib(python)) return python;
  }
  reason = "no Python with matplotlib (tried";
  for (const std::string& python : candidates) reason += " " + python;
  reason += "): install matplotlib (Debian: apt-get install python3-matplotlib) or give one with --python";
  return std::nullopt;
}

}  // namespace

CsvWriter::CsvWriter(const fs::path& path, const std::vector<std::string>& header) : path_(path), out_(path) {
  if (!out_) throw PostOutputError(path.string() + ": cannot create the file: " + std::strerror(errno));
  for (std::size_t k = 0; k < header.size(); ++k) out_ << (k ? "," : "") << header[k];
  out_ << "\n";
}

void CsvWriter::row(const std::vector<double>& values) {
  std::array<char, 32> text{};
  for (std::size_t k = 0; k < values.size(); ++k) {
    std::snprintf(text.data(), text.size(), "%.17g", values[k]);
    out_ << (k ? "," : "") << text.data();
  }
  out_ << "\n";
}

void CsvWriter::text_row(const std::vector<std::string>& values) {
  for (std::size_t k = 0; k < values.size(); ++k) out_ << (k ? "," : "") << values[k];
  out_ << "\n";
}

void CsvWriter::close() {
  out_.close();
  if (!out_) throw PostOutputError(path_.string() + ": cannot write the file: " + std::strerror(errno));
}

std::string number(double x) {
  std::array<char, 32> text{};
  std::snprintf(text.data(), text.size(), "%.17g", x);
  return text.data();
}

void create_output_directory(const fs::path& directory) {
  std::error_code error;
  fs::create_directories(directory, error);
  if (error) throw PostOutputError(directory.string() + ": cannot create the folder: " + error.message());
}

bool run_plots(const std::string& mode, const std::string& arguments, const fs::path& directory,
               const PlotOptions& options, std::ostream* log, std::ostream* warnings) {
  const auto warn = [&](const std::string& what) {
    if (warnings != nullptr) {
      *warnings << "rubble post: warning: plots not drawn: " << what << " (the CSV and HDF5 files are written)\n"
                << std::flush;
    }
    return false;
  };
  const fs::path script = options.script.empty() ? plots_script() : options.script;
  if (!fs::is_regular_file(script)) {
    return warn(script.string() + ": no such plotting script (set RUBBLE_PLOTS_SCRIPT or --plots-script)");
  }
  std::string reason;
  const std::optional<std::string> python = plotting_python(options, reason);
  if (!python) return warn(reason);
  const std::string command = shell_quote(*python) + " " + shell_quote(script.string()) + " " + mode + " " +
                              shell_quote(directory.string()) + arguments;
  if (log != nullptr) *log << "rubble post: plotting: " << command << "\n" << std::flush;
  const int status = std::system(command.c_str());
  if (status != 0) return warn("the plotting script failed: " + command);
  return true;
}

void add_plot_files(const fs::path& directory, const std::vector<std::string>& names, std::vector<fs::path>& written,
                    std::ostream* warnings) {
  for (const std::string& png : names) {
    if (fs::exists(directory / png)) {
      written.push_back(directory / png);
    } else if (warnings != nullptr) {
      *warnings << "rubble post: warning: " << (directory / png).string() << ": the plotting script did not write it\n";
    }
  }
}

void check_series(const fs::path& run_file, const RunSeries& series) {
  for (std::size_t k = 0; k < series.step.size(); ++k) {
    for (const auto& [name, value] :
         {std::pair{"time", series.time[k]}, std::pair{"kinetic_energy", series.kinetic_energy[k]},
          std::pair{"residual", series.residual[k]}}) {
      if (!std::isfinite(value)) {
        throw NonFiniteResult(run_file.string() + ": /series row " + std::to_string(k) + " (step " +
                              std::to_string(series.step[k]) + "): " + name + " = " + number(value));
      }
    }
  }
}

void check_snapshot(const fs::path& run_file, std::size_t index, const State& state) {
  for (std::size_t b = 0; b < state.body_count(); ++b) {
    const char* what = !state.position[b].allFinite()               ? "position"
                       : !state.orientation[b].coeffs().allFinite() ? "orientation"
                       : !state.velocity[b].allFinite()             ? "velocity"
                       : !state.angular_velocity[b].allFinite()     ? "angular velocity"
                                                                    : nullptr;
    if (what != nullptr) {
      const Vec3 x = state.position[b];
      throw NonFiniteResult(run_file.string() + ": snapshot " + std::to_string(index) + " (step " +
                            std::to_string(state.step) + ", t = " + number(state.time) + " s): body " +
                            std::to_string(b) + ": non-finite " + what + " (position " + number(x.x()) + ", " +
                            number(x.y()) + ", " + number(x.z()) + ")");
    }
  }
}

void check_metrics(const fs::path& run_file, std::size_t index, const std::vector<double>& row) {
  const std::vector<std::string> names = metrics_column_names();
  for (std::size_t c = 0; c < row.size(); ++c) {
    if (!std::isfinite(row[c])) {
      throw NonFiniteResult(run_file.string() + ": snapshot " + std::to_string(index) + ": metric " +
                            (c < names.size() ? names[c] : std::to_string(c)) + " = " + number(row[c]));
    }
  }
}

}  // namespace post_detail

std::filesystem::path plots_script() {
  namespace fs = std::filesystem;
  const char* override_path = std::getenv("RUBBLE_PLOTS_SCRIPT");
  if (override_path != nullptr && *override_path != '\0') return fs::path(override_path);
  std::error_code error;
  const fs::path program = fs::read_symlink("/proc/self/exe", error);
  if (!error) {
    for (const fs::path& candidate :
         {program.parent_path() / "plots.py", program.parent_path() / ".." / "share" / "rubble" / "plots.py"}) {
      if (fs::is_regular_file(candidate, error)) return candidate.lexically_normal();
    }
  }
  return fs::path(RUBBLE_PLOTS_SCRIPT);
}

}  // namespace rubble
