#include "postprocessing/post.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <numeric>
#include <optional>
#include <ostream>
#include <stdexcept>

#include "core/hdf5_io.hpp"
#include "postprocessing/run_reader.hpp"
#include "postprocessing/vtk_output.hpp"

#ifndef RUBBLE_PLOTS_SCRIPT
#define RUBBLE_PLOTS_SCRIPT "postprocessing/plots.py"
#endif

namespace rubble {
namespace {

namespace fs = std::filesystem;

/// A CSV file written column by column; numbers in the shortest form that reads back exactly.
class CsvWriter {
 public:
  CsvWriter(const fs::path& path, const std::vector<std::string>& header) : path_(path), out_(path) {
    if (!out_) throw PostOutputError(path.string() + ": cannot create the file: " + std::strerror(errno));
    for (std::size_t k = 0; k < header.size(); ++k) out_ << (k ? "," : "") << header[k];
    out_ << "\n";
  }
  void row(const std::vector<double>& values) {
    std::array<char, 32> text{};
    for (std::size_t k = 0; k < values.size(); ++k) {
      std::snprintf(text.data(), text.size(), "%.17g", values[k]);
      out_ << (k ? "," : "") << text.data();
    }
    out_ << "\n";
  }
  void text_row(const std::vector<std::string>& values) {
    for (std::size_t k = 0; k < values.size(); ++k) out_ << (k ? "," : "") << values[k];
    out_ << "\n";
  }
  void close() {
    out_.close();
    if (!out_) throw PostOutputError(path_.string() + ": cannot write the file: " + std::strerror(errno));
  }

 private:
  fs::path path_;
  std::ofstream out_;
};

std::string number(double x) {
  std::array<char, 32> text{};
  std::snprintf(text.data(), text.size(), "%.17g", x);
  return text.data();
}

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

/// Draws the PNGs of `mode` ("run" or "study") with plots.py; returns false, with a warning, when
/// it cannot (the CSV files are there all the same: plots are a convenience, not the result).
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

/// The PNGs that `plots.py run` draws for a scene of this kind (docs/postprocessing.md).
std::vector<std::string> run_plot_files(SceneKind kind) {
  if (kind == SceneKind::deposit) return {"kinetic_energy.png", "coordination.png", "impulse_distribution.png"};
  return {"kinetic_energy.png", "coordination.png", "packing_fraction.png", "aggregate_diameter.png",
          "impulse_distribution.png"};
}

/// The snapshot indices used: every `every`-th from 0, and the last one.
std::vector<std::size_t> chosen_snapshots(std::size_t count, int every) {
  std::vector<std::size_t> indices;
  const auto stride = static_cast<std::size_t>(std::max(every, 1));
  for (std::size_t k = 0; k < count; k += stride) indices.push_back(k);
  if (count > 0 && indices.back() != count - 1) indices.push_back(count - 1);
  return indices;
}

void write_metrics_hdf5(const fs::path& path, const fs::path& run_file, const std::vector<std::vector<double>>& rows,
                        const ImpulseHistogram& histogram) {
  const hdf5::QuietErrors quiet;
  hdf5::Handle file = hdf5::create_file(path);
  hdf5::write_attribute(file.get(), "format", std::string_view("rubble-metrics"), path);
  hdf5::write_attribute(file.get(), "format_version", std::int64_t{1}, path);
  hdf5::write_attribute(file.get(), "run_file", std::string_view(run_file.string()), path);
  hdf5::Handle metrics = hdf5::create_group(file.get(), "metrics", path);
  const std::vector<std::string> names = metrics_column_names();
  const std::array<hsize_t, 1> dims{rows.size()};
  for (std::size_t c = 0; c < names.size(); ++c) {
    std::vector<double> column;
    for (const auto& row : rows) column.push_back(row[c]);
    hdf5::write_doubles(metrics.get(), names[c], column, dims, path);
  }
  hdf5::Handle impulses = hdf5::create_group(file.get(), "impulse_distribution", path);
  hdf5::write_attribute(impulses.get(), "mean_normal_impulse", histogram.mean_normal_impulse, path);
  const std::array<hsize_t, 1> bins{histogram.count.size()};
  hdf5::write_doubles(impulses.get(), "bin_lower", histogram.bin_lower, bins, path);
  hdf5::write_doubles(impulses.get(), "bin_upper", histogram.bin_upper, bins, path);
  hdf5::write_int64s(impulses.get(), "count", histogram.count, bins, path);
  hdf5::write_doubles(impulses.get(), "density", histogram.density, bins, path);
  hdf5::check(H5Fflush(file.get(), H5F_SCOPE_LOCAL), path, "cannot flush");
}

/// Throws NonFiniteResult when a series row holds a non-finite time, energy or residual.
void check_series(const fs::path& run_file, const RunSeries& series) {
  for (std::size_t k = 0; k < series.step.size(); ++k) {
    for (const auto& [name, value] : {std::pair{"time", series.time[k]}, std::pair{"kinetic_energy", series.kinetic_energy[k]},
                                      std::pair{"residual", series.residual[k]}}) {
      if (!std::isfinite(value)) {
        throw NonFiniteResult(run_file.string() + ": /series row " + std::to_string(k) + " (step " +
                              std::to_string(series.step[k]) + "): " + name + " = " + number(value));
      }
    }
  }
}

/// Throws NonFiniteResult when a body of the snapshot has a non-finite position, orientation or
/// velocity: every metric of it would be NaN.
void check_snapshot(const fs::path& run_file, std::size_t index, const State& state) {
  for (std::size_t b = 0; b < state.body_count(); ++b) {
    const char* what = !state.position[b].allFinite()              ? "position"
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

/// Throws NonFiniteResult naming the first non-finite metric of a snapshot's row.
void check_metrics(const fs::path& run_file, std::size_t index, const std::vector<double>& row) {
  const std::vector<std::string> names = metrics_column_names();
  for (std::size_t c = 0; c < row.size(); ++c) {
    if (!std::isfinite(row[c])) {
      throw NonFiniteResult(run_file.string() + ": snapshot " + std::to_string(index) + ": metric " +
                            (c < names.size() ? names[c] : std::to_string(c)) + " = " + number(row[c]));
    }
  }
}

}  // namespace

fs::path plots_script() {
  const char* override_path = std::getenv("RUBBLE_PLOTS_SCRIPT");
  if (override_path != nullptr && *override_path != '\0') return fs::path(override_path);
  std::error_code error;
  const fs::path program = fs::read_symlink("/proc/self/exe", error);
  if (!error) {
    for (const fs::path& candidate : {program.parent_path() / "plots.py", program.parent_path() / ".." / "share" / "rubble" / "plots.py"}) {
      if (fs::is_regular_file(candidate, error)) return candidate.lexically_normal();
    }
  }
  return fs::path(RUBBLE_PLOTS_SCRIPT);
}

std::vector<fs::path> post_process_run(const fs::path& run_file, const PostOptions& options) {
  const RunReader reader = RunReader::open(run_file);
  if (reader.live() && options.warnings != nullptr) {
    *options.warnings << "rubble post: note: " << run_file.string()
                      << " is being written by a running `rubble run`: reading a run in progress, as of its last "
                         "checkpoint (status "
                      << reader.status() << ")\n";
  }
  const Model& model = reader.model();
  const fs::path out = options.output_directory;
  std::error_code error;
  fs::create_directories(out, error);
  if (error) throw PostOutputError(out.string() + ": cannot create the folder: " + error.message());
  std::vector<fs::path> written;
  std::int64_t grains = 0;
  for (std::size_t i = 0; i < model.body_count(); ++i) grains += model.is_grain(i) ? 1 : 0;

  // The per-step series, with the mean kinetic energy per grain.
  const RunSeries series = reader.read_series();
  check_series(run_file, series);
  {
    const fs::path path = out / "series.csv";
    std::vector<std::string> header{"step",           "time",       "kinetic_energy", "mean_kinetic_energy", "contacts",
                                    "active_contacts", "iterations", "residual",       "wall_seconds"};
    header.insert(header.end(), series.monitor_names.begin(), series.monitor_names.end());
    CsvWriter csv(path, header);
    for (std::size_t k = 0; k < series.step.size(); ++k) {
      std::vector<double> row{static_cast<double>(series.step[k]), series.time[k], series.kinetic_energy[k],
                              grains > 0 ? series.kinetic_energy[k] / static_cast<double>(grains) : 0.0,
                              static_cast<double>(series.contacts[k]), static_cast<double>(series.active_contacts[k]),
                              static_cast<double>(series.iterations[k]), series.residual[k], series.wall_seconds[k]};
      for (const std::vector<double>& column : series.monitor) row.push_back(column[k]);
      csv.row(row);
    }
    csv.close();
    written.push_back(path);
  }

  // Metrics of every chosen snapshot, the impulse distribution of the last one, VTK on request.
  const double h = options.time_step > 0.0 ? options.time_step : reader.time_step();
  std::unique_ptr<VtkSeries> vtk;
  if (options.write_vtk) vtk = std::make_unique<VtkSeries>(out / "vtk", model, VtkSeriesOptions{h, 0.0, {}});
  std::vector<std::vector<double>> rows;
  ImpulseHistogram histogram;
  const std::vector<std::size_t> indices = chosen_snapshots(reader.snapshot_count(), options.every);
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const RunSnapshot snapshot = reader.read_snapshot(indices[k]);
    check_snapshot(run_file, indices[k], snapshot.state);
    rows.push_back(metrics_row(compute_metrics(model, snapshot.state, snapshot.contacts, options.potential)));
    check_metrics(run_file, indices[k], rows.back());
    if (vtk) vtk->write(snapshot.state, snapshot.contacts);
    if (k + 1 == indices.size()) histogram = normal_impulse_histogram(snapshot.contacts, options.histogram_bins);
    if (options.log != nullptr && (k % 20 == 0 || k + 1 == indices.size())) {
      *options.log << "rubble post: snapshot " << indices[k] + 1 << " / " << reader.snapshot_count() << "\n"
                   << std::flush;
    }
  }
  {
    const fs::path path = out / "metrics.csv";
    CsvWriter csv(path, metrics_column_names());
    for (const auto& row : rows) csv.row(row);
    csv.close();
    written.push_back(path);
  }
  {
    const fs::path path = out / "impulse_distribution.csv";
    CsvWriter csv(path, {"bin_lower", "bin_upper", "count", "density"});
    for (std::size_t b = 0; b < histogram.count.size(); ++b) {
      csv.row({histogram.bin_lower[b], histogram.bin_upper[b], static_cast<double>(histogram.count[b]),
               histogram.density[b]});
    }
    csv.close();
    written.push_back(path);
  }
  try {
    write_metrics_hdf5(out / "metrics.h5", run_file, rows, histogram);
  } catch (const std::runtime_error& error) {
    throw PostOutputError(error.what());
  }
  written.push_back(out / "metrics.h5");
  if (vtk) {
    for (const fs::path& collection : vtk->collections()) written.push_back(collection);
  }
  if (options.plots) {
    const SceneKind kind = options.scene_kind.value_or(
        options.potential.kind == PotentialSettings::Kind::self ? SceneKind::aggregate : SceneKind::deposit);
    const std::string arguments = kind == SceneKind::aggregate ? " --scene aggregate" : " --scene deposit";
    if (run_plots("run", arguments, out, options.plot, options.log, options.warnings)) {
      for (const std::string& png : run_plot_files(kind)) {
        if (fs::exists(out / png)) {
          written.push_back(out / png);
        } else if (options.warnings != nullptr) {
          *options.warnings << "rubble post: warning: " << (out / png).string() << ": the plotting script did not write it\n";
        }
      }
      if (fs::exists(out / "conservation.png")) written.push_back(out / "conservation.png");
    }
  }
  if (options.log != nullptr) {
    for (const fs::path& path : written) *options.log << "  " << path.string() << "\n";
  }
  return written;
}

std::vector<fs::path> post_process_study(const std::vector<fs::path>& inputs, const StudyOptions& options) {
  // Collect the run files, in a fixed order.
  std::vector<fs::path> runs;
  for (const fs::path& input : inputs) {
    if (fs::is_directory(input)) {
      for (const auto& entry : fs::recursive_directory_iterator(input)) {
        if (entry.is_regular_file() && entry.path().extension() == ".h5") runs.push_back(entry.path());
      }
    } else if (fs::exists(input)) {
      runs.push_back(input);
    } else {
      throw std::runtime_error(input.string() + ": no such file or folder");
    }
  }
  std::sort(runs.begin(), runs.end());
  const fs::path out = options.output_directory;
  std::error_code error;
  fs::create_directories(out, error);
  if (error) throw PostOutputError(out.string() + ": cannot create the folder: " + error.message());

  const fs::path path = out / "study.csv";
  CsvWriter csv(path, {"run", "status", "included", "shape", "grains", "friction", "snapshots_used", "window_start", "Z_max",
                       "Z_without_rattlers", "D_max", "mean_diameter", "equivalent_diameter", "D_max_over_mean_d",
                       "D_max_over_d_star", "packing_fraction", "inner_packing_fraction", "peak_mean_kinetic_energy"});
  int used = 0;
  std::vector<std::string> left_out;  // runs that did not end at rest, with their status
  for (const fs::path& run : runs) {
    std::unique_ptr<RunReader> reader;
    try {
      reader = std::make_unique<RunReader>(RunReader::open(run));
    } catch (const std::runtime_error& e) {
      // Folders also hold metrics.h5 and other HDF5 files: only run files take part.
      if (options.log != nullptr) *options.log << "rubble post: skipping " << e.what() << "\n";
      continue;
    }
    const Model& model = reader->model();
    // A run stopped mid-collapse (interrupted, killed, failed, or cut by its end time) is not a
    // rubble pile at rest: its "stabilised" averages would sit beside finished runs' as if
    // comparable. Listed with its status; averaged and plotted only when asked.
    const std::string status = reader->status();
    const bool finished = status == "at_rest";
    if (!finished) {
      left_out.push_back(run.string() + " (" + status + ")");
      if (options.log != nullptr) {
        *options.log << "rubble post: study: " << run.string() << " did not end at rest (status " << status << "): "
                     << (options.include_unfinished ? "included (--include-unfinished), marked in study.csv and the plots"
                                                    : "listed in study.csv, left out of the plots (--include-unfinished "
                                                      "to include it)")
                     << "\n";
      }
    }
    const bool included = finished || options.include_unfinished;
    if (reader->snapshot_count() == 0) {
      if (options.log != nullptr) *options.log << "rubble post: skipping " << run.string() << ": no snapshot\n";
      continue;
    }
    // Shape family and friction of the grains' contact law(s).
    int spheres = 0, polyhedra = 0;
    std::vector<int> materials;
    for (std::size_t i = 0; i < model.body_count(); ++i) {
      if (!model.is_grain(i)) continue;
      (model.shape_kind[i] == ShapeKind::sphere ? spheres : polyhedra) += 1;
      materials.push_back(model.material[i]);
    }
    std::sort(materials.begin(), materials.end());
    materials.erase(std::unique(materials.begin(), materials.end()), materials.end());
    double friction = 0.0;
    int pairs = 0;
    for (int a : materials) {
      for (int b : materials) {
        if (b < a) continue;
        friction += model.contact_laws.get(a, b).friction_coefficient;
        ++pairs;
      }
    }
    friction = pairs > 0 ? friction / pairs : 0.0;  // the mean over grain material pairs (one pair in the study)
    const std::string shape = polyhedra == 0 ? "spheres" : spheres == 0 ? "polyhedra" : "mixed";

    // The stabilised window: snapshots at t >= stable_after, else the last quarter.
    std::vector<AggregateMetrics> all;
    for (std::size_t k = 0; k < reader->snapshot_count(); ++k) {
      const RunSnapshot snapshot = reader->read_snapshot(k);
      check_snapshot(run, k, snapshot.state);
      all.push_back(compute_metrics(model, snapshot.state, snapshot.contacts));
      check_metrics(run, k, metrics_row(all.back()));
    }
    std::vector<const AggregateMetrics*> window;
    for (const AggregateMetrics& m : all) {
      if (m.time >= options.stable_after) window.push_back(&m);
    }
    if (window.empty()) {
      const std::size_t start = all.size() - std::max<std::size_t>(1, all.size() / 4);
      for (std::size_t k = start; k < all.size(); ++k) window.push_back(&all[k]);
    }
    const auto mean = [&](auto field) {
      double sum = 0.0;
      for (const AggregateMetrics* m : window) sum += field(*m);
      return sum / static_cast<double>(window.size());
    };
    const RunSeries series = reader->read_series();
    check_series(run, series);
    const double grains = static_cast<double>(all.front().grains);
    const double peak_energy =
        series.kinetic_energy.empty() || grains == 0
            ? 0.0
            : *std::max_element(series.kinetic_energy.begin(), series.kinetic_energy.end()) / grains;
    const double d_max = mean([](const AggregateMetrics& m) { return m.aggregate_diameter; });
    const double d_mean = mean([](const AggregateMetrics& m) { return m.mean_diameter; });
    const double d_star = mean([](const AggregateMetrics& m) { return m.equivalent_diameter; });
    csv.text_row({run.string(), status, included ? "1" : "0", shape, number(grains), number(friction), std::to_string(window.size()),
                  number(window.front()->time), number(mean([](const AggregateMetrics& m) { return m.coordination; })),
                  number(mean([](const AggregateMetrics& m) { return m.coordination_without_rattlers; })), number(d_max),
                  number(d_mean), number(d_star), number(d_mean > 0 ? d_max / d_mean : 0.0),
                  number(d_star > 0 ? d_max / d_star : 0.0),
                  number(mean([](const AggregateMetrics& m) { return m.packing_fraction; })),
                  number(mean([](const AggregateMetrics& m) { return m.inner_packing_fraction; })), number(peak_energy)});
    used += included ? 1 : 0;
    if (options.log != nullptr) *options.log << "rubble post: study: " << run.string() << " (" << shape << ", n_s = " << grains << ", mu = " << friction << ")\n";
  }
  csv.close();
  if (used == 0) {
    std::string message = "rubble post --study: no run file with snapshots that ended at rest found in the given paths";
    if (!left_out.empty()) {
      message += "; " + std::to_string(left_out.size()) + " did not end at rest:";
      for (const std::string& run : left_out) message += " " + run;
      message += " (--include-unfinished includes them)";
    }
    throw std::runtime_error(message);
  }
  std::vector<fs::path> written{path};
  if (options.plots && run_plots("study", "", out, options.plot, options.log, options.warnings)) {
    for (const char* png : {"study_coordination_vs_ns.png", "study_diameter_vs_ns.png", "study_packing_vs_ns.png",
                            "study_coordination_vs_mu.png", "study_diameter_vs_mu.png", "study_packing_vs_mu.png",
                            "study_peak_energy_vs_ns.png"}) {
      if (fs::exists(out / png)) {
        written.push_back(out / png);
      } else if (options.warnings != nullptr) {
        *options.warnings << "rubble post: warning: " << (out / png).string() << ": the plotting script did not write it\n";
      }
    }
  }
  return written;
}

}  // namespace rubble
