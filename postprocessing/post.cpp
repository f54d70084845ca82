#include "postprocessing/post.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <numeric>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <tuple>

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
    column.reserve(rows.size());
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

/// Throws NonFiniteResult when a body of the snapshot has a non-finite position, orientation or
/// velocity: every metric of it would be NaN.
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
    for (const fs::path& candidate :
         {program.parent_path() / "plots.py", program.parent_path() / ".." / "share" / "rubble" / "plots.py"}) {
      if (fs::is_regular_file(candidate, error)) return candidate.lexically_normal();
    }
  }
  return fs::path(RUBBLE_PLOTS_SCRIPT);
}

// NOLINTNEXTLINE(readability-function-size): over 80 lines, listed in docs/architecture.md
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
    std::vector<std::string> header{
        "step",       "time",     "kinetic_energy", "mean_kinetic_energy", "contacts", "active_contacts",
        "iterations", "residual", "wall_seconds"};
    header.insert(header.end(), series.monitor_names.begin(), series.monitor_names.end());
    CsvWriter csv(path, header);
    for (std::size_t k = 0; k < series.step.size(); ++k) {
      std::vector<double> row{static_cast<double>(series.step[k]),
                              series.time[k],
                              series.kinetic_energy[k],
                              grains > 0 ? series.kinetic_energy[k] / static_cast<double>(grains) : 0.0,
                              static_cast<double>(series.contacts[k]),
                              static_cast<double>(series.active_contacts[k]),
                              static_cast<double>(series.iterations[k]),
                              series.residual[k],
                              series.wall_seconds[k]};
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
  const GrainSizes sizes = grain_sizes(model);  // once per run: one enclosing ball per polyhedron
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const RunSnapshot snapshot = reader.read_snapshot(indices[k]);
    check_snapshot(run_file, indices[k], snapshot.state);
    rows.push_back(metrics_row(compute_metrics(model, sizes, snapshot.state, snapshot.contacts, options.potential)));
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
          *options.warnings << "rubble post: warning: " << (out / png).string()
                            << ": the plotting script did not write it\n";
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

namespace {

/// x with 4 significant digits (the study table: a window mean is not known to 17 digits), in
/// fixed notation between 1e-3 and 1e6 so that times and counts read plainly; empty for NaN (a
/// quantity that does not apply, such as the rest time of a run not at rest).
std::string significant(double x) {
  if (std::isnan(x)) return "";
  std::array<char, 48> text{};
  const double magnitude = std::abs(x);
  if (x == 0.0) return "0";
  if (magnitude >= 1e-3 && magnitude < 1e6) {
    const int decimals = std::max(0, 3 - static_cast<int>(std::floor(std::log10(magnitude))));
    std::snprintf(text.data(), text.size(), "%.*f", decimals, x);
  } else {
    std::snprintf(text.data(), text.size(), "%.3e", x);
  }
  return text.data();
}

/// A parameter of the run (mu, the window's start) as given: 0.4, not 0.4000.
std::string parameter_text(double x) {
  std::array<char, 32> text{};
  std::snprintf(text.data(), text.size(), "%.6g", x);
  return text.data();
}

/// A count (grains, snapshots) as an integer.
std::string count_text(double x) { return std::to_string(std::llround(x)); }

/// Mean and standard deviation (n - 1 in the denominator; 0 for one value).
struct Spread {
  double mean = 0.0;
  double deviation = 0.0;
};
Spread spread(const std::vector<double>& values) {
  Spread s;
  if (values.empty()) return {std::nan(""), std::nan("")};
  for (double v : values) s.mean += v;
  s.mean /= static_cast<double>(values.size());
  if (values.size() > 1) {
    double sum = 0.0;
    for (double v : values) sum += (v - s.mean) * (v - s.mean);
    s.deviation = std::sqrt(sum / static_cast<double>(values.size() - 1));
  }
  return s;
}

/// One run of a study, reduced to the quantities of the study table.
struct StudyRun {
  std::string path, status, shape, averaged_over;
  bool at_rest = false, reached_window = false, included = false;
  double grains = 0.0, friction = 0.0, end_time = 0.0;
  std::size_t snapshots_used = 0;
  double peak_time = 0.0, peak_energy = 0.0, rest_time = std::nan(""), plateau = std::nan("");
  std::map<std::string, Spread> values;  // window mean and spread of each averaged metric
  double max_overlap = 0.0, detached = 0.0, escaping = 0.0;
  std::vector<double> energy_time, energy;  // <E_c>(t), thinned for the plot
};

/// Least-squares line y = a + b x; returns {a, b, rms residual}.
std::array<double, 3> fit_line(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    sx += x[k];
    sy += y[k];
    sxx += x[k] * x[k];
    sxy += x[k] * y[k];
  }
  const double b = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  const double a = (sy - b * sx) / n;
  double r = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k) r += (y[k] - a - b * x[k]) * (y[k] - a - b * x[k]);
  return {a, b, std::sqrt(r / n)};
}

}  // namespace

// NOLINTNEXTLINE(readability-function-size): over 80 lines, listed in docs/architecture.md
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

  // The metrics averaged over the window, by study.csv column name.
  using Field = double (*)(const AggregateMetrics&);
  const std::vector<std::pair<std::string, Field>> averaged{
      {"Z_max", [](const AggregateMetrics& m) { return m.coordination; }},
      {"Z_without_rattlers", [](const AggregateMetrics& m) { return m.coordination_without_rattlers; }},
      {"rattlers", [](const AggregateMetrics& m) { return static_cast<double>(m.rattlers); }},
      {"packing_fraction", [](const AggregateMetrics& m) { return m.packing_fraction; }},
      {"inertia_packing_fraction", [](const AggregateMetrics& m) { return m.inertia_packing_fraction; }},
      {"inner_packing_fraction", [](const AggregateMetrics& m) { return m.inner_packing_fraction; }},
      {"D_max", [](const AggregateMetrics& m) { return m.aggregate_diameter; }},
      {"mean_diameter", [](const AggregateMetrics& m) { return m.mean_diameter; }},
      {"equivalent_diameter", [](const AggregateMetrics& m) { return m.equivalent_diameter; }},
      {"D_max_over_mean_d", [](const AggregateMetrics& m) { return m.aggregate_diameter / m.mean_diameter; }},
      {"D_max_over_d_star", [](const AggregateMetrics& m) { return m.aggregate_diameter / m.equivalent_diameter; }},
      {"inertia_aspect_ratio", [](const AggregateMetrics& m) { return m.inertia_aspect_ratio; }},
  };

  std::vector<StudyRun> study;
  std::vector<std::string> left_out;  // runs left out of the plots and fits, with the reason
  for (const fs::path& run : runs) {
    std::unique_ptr<RunReader> reader;
    try {
      reader = std::make_unique<RunReader>(RunReader::open(run));
    } catch (const std::runtime_error& e) {
      // Folders also hold metrics.h5 and other HDF5 files: only run files take part.
      if (options.log != nullptr) *options.log << "rubble post: skipping " << e.what() << "\n";
      continue;
    }
    if (reader->snapshot_count() == 0) {
      if (options.log != nullptr) *options.log << "rubble post: skipping " << run.string() << ": no snapshot\n";
      continue;
    }
    const Model& model = reader->model();
    StudyRun r;
    r.path = run.string();
    r.status = reader->status();
    r.at_rest = r.status == "at_rest";
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
    int pairs = 0;
    for (int a : materials) {
      for (int b : materials) {
        if (b < a) continue;
        r.friction += model.contact_laws.get(a, b).friction_coefficient;
        ++pairs;
      }
    }
    r.friction = pairs > 0 ? r.friction / pairs : 0.0;  // the mean over grain material pairs (one pair in the study)
    r.shape = polyhedra == 0 ? "spheres" : spheres == 0 ? "polyhedra" : "mixed";
    r.grains = spheres + polyhedra;

    // Every snapshot's metrics (grain sizes once per run); the last one also with the run's
    // gravity, for the escape test (an O(N^2) direct sum, so not at every snapshot).
    const GrainSizes sizes = grain_sizes(model);
    const PotentialSettings potential = options.potential_of ? options.potential_of(*reader) : PotentialSettings{};
    std::vector<AggregateMetrics> all;
    for (std::size_t k = 0; k < reader->snapshot_count(); ++k) {
      const RunSnapshot snapshot = reader->read_snapshot(k);
      check_snapshot(run, k, snapshot.state);
      const bool last = k + 1 == reader->snapshot_count();
      all.push_back(
          compute_metrics(model, sizes, snapshot.state, snapshot.contacts, last ? potential : PotentialSettings{}));
      check_metrics(run, k, metrics_row(all.back()));
    }
    r.end_time = all.back().time;
    r.detached = static_cast<double>(all.back().detached_grains);
    r.escaping = static_cast<double>(all.back().escaping_grains);

    // The window t >= stable_after (the paper's stabilised regime), never replaced: a run that
    // did not reach it is reported at its final snapshot, flagged, and left out by default.
    std::vector<const AggregateMetrics*> window;
    for (const AggregateMetrics& m : all) {
      if (m.time >= options.stable_after) window.push_back(&m);
    }
    r.reached_window = !window.empty();
    if (!r.reached_window) window.push_back(&all.back());
    r.averaged_over = r.reached_window ? "window" : "final_snapshot";
    r.snapshots_used = window.size();
    for (const auto& [name, field] : averaged) {
      std::vector<double> values;
      values.reserve(window.size());
      for (const AggregateMetrics* m : window) values.push_back(field(*m));
      r.values[name] = spread(values);
    }
    for (const AggregateMetrics* m : window) r.max_overlap = std::max(r.max_overlap, m->max_overlap);

    // <E_c>(t) from the per-step series: peak, plateau over the window, the curve (thinned to
    // ~2000 points, the peak kept) for the overlay plot.
    const RunSeries series = reader->read_series();
    check_series(run, series);
    if (!series.time.empty() && r.grains > 0) {
      const auto peak = static_cast<std::size_t>(
          std::max_element(series.kinetic_energy.begin(), series.kinetic_energy.end()) - series.kinetic_energy.begin());
      r.peak_time = series.time[peak];
      r.peak_energy = series.kinetic_energy[peak] / r.grains;
      std::vector<double> plateau;
      const std::size_t stride = std::max<std::size_t>(1, series.time.size() / 2000);
      for (std::size_t k = 0; k < series.time.size(); ++k) {
        if (series.time[k] >= options.stable_after) plateau.push_back(series.kinetic_energy[k] / r.grains);
        if (k % stride == 0 || k == peak || k + 1 == series.time.size()) {
          r.energy_time.push_back(series.time[k]);
          r.energy.push_back(series.kinetic_energy[k] / r.grains);
        }
      }
      if (!plateau.empty()) r.plateau = spread(plateau).mean;
      if (r.at_rest) r.rest_time = series.time.back();
    }
    r.included = (r.at_rest && r.reached_window) || options.include_unfinished;
    if (!r.at_rest || !r.reached_window) {
      std::string why = !r.at_rest ? "did not end at rest (status " + r.status + ")" : "";
      if (!r.reached_window) {
        why += (why.empty() ? "" : " and ") + std::string("did not reach the window t >= ") +
               parameter_text(options.stable_after) + " s (ended at t = " + significant(r.end_time) +
               " s; its final snapshot is reported instead, averaged_over = final_snapshot)";
      }
      left_out.push_back(r.path + " (" + why + ")");
      if (options.warnings != nullptr) {
        *options.warnings << "rubble post: study: " << r.path << " " << why << ": "
                          << (options.include_unfinished
                                  ? "included (--include-unfinished), flagged in study.csv and the plots"
                                  : "flagged in study.csv, left out of the fits and plots "
                                    "(--include-unfinished includes it)")
                          << "\n";
      }
    }
    if (options.log != nullptr) {
      *options.log << "rubble post: study: " << r.path << " (" << r.shape << ", n_s = " << r.grains
                   << ", mu = " << parameter_text(r.friction) << ", " << r.snapshots_used << " snapshots in the "
                   << (r.reached_window ? "window" : "final state") << ")\n";
    }
    study.push_back(std::move(r));
  }

  // Rows by shape, mu, n_s (then path: seeds side by side), the order a reader compares them in.
  std::stable_sort(study.begin(), study.end(), [](const StudyRun& a, const StudyRun& b) {
    return std::tie(a.shape, a.friction, a.grains, a.path) < std::tie(b.shape, b.friction, b.grains, b.path);
  });
  std::vector<fs::path> written;
  {
    const fs::path path = out / "study.csv";
    std::vector<std::string> header{"run",
                                    "status",
                                    "reached_window",
                                    "included",
                                    "shape",
                                    "grains",
                                    "friction",
                                    "window_start",
                                    "end_time",
                                    "averaged_over",
                                    "snapshots_used",
                                    "peak_time",
                                    "peak_mean_kinetic_energy",
                                    "rest_time",
                                    "plateau_mean_kinetic_energy"};
    // Grain diameters do not change during a run: no spread column for them.
    const auto has_spread = [](const std::string& name) {
      return name != "mean_diameter" && name != "equivalent_diameter";
    };
    for (const auto& [name, field] : averaged) {
      header.push_back(name);
      if (has_spread(name)) header.push_back(name + "_spread");
    }
    header.insert(header.end(), {"max_overlap", "max_overlap_over_mean_d", "detached_grains", "escaping_grains"});
    CsvWriter csv(path, header);
    for (const StudyRun& r : study) {
      std::vector<std::string> row{r.path,
                                   r.status,
                                   r.reached_window ? "1" : "0",
                                   r.included ? "1" : "0",
                                   r.shape,
                                   count_text(r.grains),
                                   parameter_text(r.friction),
                                   parameter_text(options.stable_after),
                                   significant(r.end_time),
                                   r.averaged_over,
                                   std::to_string(r.snapshots_used),
                                   significant(r.peak_time),
                                   significant(r.peak_energy),
                                   significant(r.rest_time),
                                   significant(r.plateau)};
      for (const auto& [name, field] : averaged) {
        row.push_back(significant(r.values.at(name).mean));
        if (has_spread(name)) row.push_back(significant(r.values.at(name).deviation));
      }
      row.insert(row.end(), {significant(r.max_overlap), significant(r.max_overlap / r.values.at("mean_diameter").mean),
                             count_text(r.detached), count_text(r.escaping)});
      csv.text_row(row);
    }
    csv.close();
    written.push_back(path);
  }
  const auto used = std::count_if(study.begin(), study.end(), [](const StudyRun& r) { return r.included; });
  if (used == 0) {
    std::string message = "rubble post --study: no run file with snapshots that ended at rest in the window t >= " +
                          parameter_text(options.stable_after) + " s found in the given paths";
    if (!left_out.empty()) {
      message += "; " + std::to_string(left_out.size()) + " left out:";
      for (const std::string& run : left_out) message += " " + run;
      message += " (--include-unfinished includes them; --stable-after sets the window)";
    }
    message += " (study.csv lists every run)";
    throw std::runtime_error(message);
  }

  // Power-law fits y = a n_s^b per (shape, mu) series of the included runs (every run a point, so
  // seeds weigh as runs), by least squares on the logarithms; the peak <E_c> also as an
  // exponential y = a exp(b n_s), on log y, to weigh the paper's "exponential" against a power law.
  {
    const fs::path path = out / "study_fits.csv";
    CsvWriter csv(path,
                  {"shape", "friction", "quantity", "model", "prefactor", "exponent", "points", "rms_log_residual"});
    std::vector<std::pair<std::string, double>> series;
    for (const StudyRun& r : study) {
      if (r.included && std::find(series.begin(), series.end(), std::pair{r.shape, r.friction}) == series.end()) {
        series.emplace_back(r.shape, r.friction);
      }
    }
    for (const auto& [shape, friction] : series) {
      for (const std::string quantity : {"D_max_over_mean_d", "D_max_over_d_star", "peak_mean_kinetic_energy"}) {
        std::vector<double> log_n, n, log_y;
        for (const StudyRun& r : study) {
          if (!r.included || r.shape != shape || r.friction != friction) continue;
          const double y = quantity == "peak_mean_kinetic_energy" ? r.peak_energy : r.values.at(quantity).mean;
          if (!(y > 0.0)) continue;
          n.push_back(r.grains);
          log_n.push_back(std::log(r.grains));
          log_y.push_back(std::log(y));
        }
        if (std::set<double>(n.begin(), n.end()).size() < 2) continue;  // a fit needs two n_s
        const auto power = fit_line(log_n, log_y);
        csv.text_row({shape, parameter_text(friction), quantity, "power", significant(std::exp(power[0])),
                      significant(power[1]), std::to_string(n.size()), significant(power[2])});
        if (quantity == "peak_mean_kinetic_energy") {
          const auto exponential = fit_line(n, log_y);
          csv.text_row({shape, parameter_text(friction), quantity, "exponential", significant(std::exp(exponential[0])),
                        significant(exponential[1]), std::to_string(n.size()), significant(exponential[2])});
        }
      }
    }
    csv.close();
    written.push_back(path);
  }
  {
    const fs::path path = out / "study_kinetic_energy.csv";
    CsvWriter csv(path, {"row", "time", "mean_kinetic_energy"});
    for (std::size_t k = 0; k < study.size(); ++k) {
      for (std::size_t j = 0; j < study[k].energy.size(); ++j) {
        csv.row({static_cast<double>(k), study[k].energy_time[j], study[k].energy[j]});
      }
    }
    csv.close();
    written.push_back(path);
  }

  // The table a reader compares with the paper, aligned, at 4 significant digits.
  {
    const fs::path path = out / "study.txt";
    std::ofstream text(path);
    if (!text) throw PostOutputError(path.string() + ": cannot create the file: " + std::strerror(errno));
    std::array<char, 512> line{};
    std::snprintf(line.data(), line.size(),
                  "Window: t >= %s s (%s min). Values: mean over the window's snapshots; runs marked * did not "
                  "reach the window (final snapshot shown), ! did not end at rest; both are left out of the fits "
                  "and plots unless --include-unfinished.\n",
                  parameter_text(options.stable_after).c_str(), parameter_text(options.stable_after / 60.0).c_str());
    text << line.data();
    std::snprintf(line.data(), line.size(), "%-9s %6s %6s %2s %8s %8s %9s %6s %6s %6s %6s %8s %8s %9s %5s %5s\n",
                  "shape", "n_s", "mu", "", "peak_min", "rest_min", "plateau_J", "Z", "Z_nr", "nu", "nu_I", "D/<d>",
                  "D/d*", "overlap/d", "det", "esc");
    text << line.data();
    for (const StudyRun& r : study) {
      const std::string flag = std::string(r.reached_window ? "" : "*") + (r.at_rest ? "" : "!");
      std::snprintf(line.data(), line.size(), "%-9s %6s %6s %2s %8s %8s %9s %6s %6s %6s %6s %8s %8s %9s %5s %5s\n",
                    r.shape.c_str(), count_text(r.grains).c_str(), parameter_text(r.friction).c_str(), flag.c_str(),
                    significant(r.peak_time / 60.0).c_str(), r.at_rest ? significant(r.rest_time / 60.0).c_str() : "-",
                    r.reached_window ? significant(r.plateau).c_str() : "-",
                    significant(r.values.at("Z_max").mean).c_str(),
                    significant(r.values.at("Z_without_rattlers").mean).c_str(),
                    significant(r.values.at("packing_fraction").mean).c_str(),
                    significant(r.values.at("inertia_packing_fraction").mean).c_str(),
                    significant(r.values.at("D_max_over_mean_d").mean).c_str(),
                    significant(r.values.at("D_max_over_d_star").mean).c_str(),
                    significant(r.max_overlap / r.values.at("mean_diameter").mean).c_str(),
                    count_text(r.detached).c_str(), count_text(r.escaping).c_str());
      text << line.data();
    }
    text.close();
    if (!text) throw PostOutputError(path.string() + ": cannot write the file: " + std::strerror(errno));
    written.push_back(path);
    if (options.log != nullptr) {
      std::ifstream back(path);
      *options.log << back.rdbuf();
    }
  }

  if (options.plots && run_plots("study", "", out, options.plot, options.log, options.warnings)) {
    for (const char* png : {"study_kinetic_energy.png", "study_coordination.png", "study_diameter.png",
                            "study_packing.png", "study_peak_energy.png"}) {
      if (fs::exists(out / png)) {
        written.push_back(out / png);
      } else if (options.warnings != nullptr) {
        *options.warnings << "rubble post: warning: " << (out / png).string()
                          << ": the plotting script did not write it\n";
      }
    }
  }
  return written;
}

}  // namespace rubble
