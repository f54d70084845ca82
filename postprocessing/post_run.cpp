// post_process_run: one run file to series.csv, metrics.csv/.h5, impulse_distribution.csv, the
// ParaView series on request and the run's PNGs (docs/postprocessing.md lists every file).
#include <algorithm>
#include <array>
#include <memory>
#include <ostream>
#include <stdexcept>

#include "core/hdf5_io.hpp"
#include "postprocessing/post.hpp"
#include "postprocessing/post_detail.hpp"
#include "postprocessing/run_reader.hpp"
#include "postprocessing/vtk_output.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;
using post_detail::CsvWriter;

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

/// series.csv: the per-step series, with the mean kinetic energy per grain and the conservation
/// monitor's columns when the file has them.
fs::path write_series_csv(const fs::path& path, const RunSeries& series, std::int64_t grains) {
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
  return path;
}

/// The metrics of the chosen snapshots (one metrics_row each) and the impulse distribution of the
/// last one.
struct SnapshotMetrics {
  std::vector<std::vector<double>> rows;
  ImpulseHistogram histogram;
};

/// Metrics of every chosen snapshot, each checked finite; each snapshot also into `vtk` if given.
/// A run with [[inflow]] (`in_play` given): each snapshot's bodies in play, in `in_play` (the
/// model `vtk` was made with), the grains not inserted yet left out.
SnapshotMetrics compute_snapshot_metrics(const RunReader& reader, const fs::path& run_file, const PostOptions& options,
                                         Model* in_play, VtkSeries* vtk) {
  const Model& model = reader.model();
  SnapshotMetrics result;
  const std::vector<std::size_t> indices = chosen_snapshots(reader.snapshot_count(), options.every);
  // Once per run: one enclosing ball per polyhedron; by body id, so valid for the bodies in play too.
  const GrainSizes sizes = grain_sizes(model);
  for (std::size_t k = 0; k < indices.size(); ++k) {
    RunSnapshot snapshot = reader.read_snapshot(indices[k]);
    if (in_play != nullptr) {
      snapshot.state = state_prefix(snapshot.state, snapshot.bodies_in_play);
      if (in_play->body_count() != snapshot.bodies_in_play) *in_play = model_prefix(model, snapshot.bodies_in_play);
    }
    const Model& bodies = in_play != nullptr ? *in_play : model;
    post_detail::check_snapshot(run_file, indices[k], snapshot.state);
    result.rows.push_back(
        metrics_row(compute_metrics(bodies, sizes, snapshot.state, snapshot.contacts, options.potential)));
    post_detail::check_metrics(run_file, indices[k], result.rows.back());
    if (vtk != nullptr) vtk->write(snapshot.state, snapshot.contacts);
    if (k + 1 == indices.size()) result.histogram = normal_impulse_histogram(snapshot.contacts, options.histogram_bins);
    if (options.log != nullptr && (k % 20 == 0 || k + 1 == indices.size())) {
      *options.log << "rubble post: snapshot " << indices[k] + 1 << " / " << reader.snapshot_count() << "\n"
                   << std::flush;
    }
  }
  return result;
}

/// metrics.h5: the metrics columns and the impulse distribution (docs/postprocessing.md).
void write_metrics_hdf5(const fs::path& path, const fs::path& run_file, const SnapshotMetrics& metrics) {
  const std::vector<std::vector<double>>& rows = metrics.rows;
  const ImpulseHistogram& histogram = metrics.histogram;
  const hdf5::QuietErrors quiet;
  hdf5::Handle file = hdf5::create_file(path);
  hdf5::write_attribute(file.get(), "format", std::string_view("rubble-metrics"), path);
  hdf5::write_attribute(file.get(), "format_version", std::int64_t{1}, path);
  hdf5::write_attribute(file.get(), "run_file", std::string_view(run_file.string()), path);
  hdf5::Handle group = hdf5::create_group(file.get(), "metrics", path);
  const std::vector<std::string> names = metrics_column_names();
  const std::array<hsize_t, 1> dims{rows.size()};
  for (std::size_t c = 0; c < names.size(); ++c) {
    std::vector<double> column;
    column.reserve(rows.size());
    for (const auto& row : rows) column.push_back(row[c]);
    hdf5::write_doubles(group.get(), names[c], column, dims, path);
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

/// metrics.csv, impulse_distribution.csv and metrics.h5 in `out`, appended to `written`.
void write_metrics_files(const fs::path& out, const fs::path& run_file, const SnapshotMetrics& metrics,
                         std::vector<fs::path>& written) {
  {
    const fs::path path = out / "metrics.csv";
    CsvWriter csv(path, metrics_column_names());
    for (const auto& row : metrics.rows) csv.row(row);
    csv.close();
    written.push_back(path);
  }
  {
    const fs::path path = out / "impulse_distribution.csv";
    const ImpulseHistogram& histogram = metrics.histogram;
    CsvWriter csv(path, {"bin_lower", "bin_upper", "count", "density"});
    for (std::size_t b = 0; b < histogram.count.size(); ++b) {
      csv.row({histogram.bin_lower[b], histogram.bin_upper[b], static_cast<double>(histogram.count[b]),
               histogram.density[b]});
    }
    csv.close();
    written.push_back(path);
  }
  try {
    write_metrics_hdf5(out / "metrics.h5", run_file, metrics);
  } catch (const std::runtime_error& error) {
    throw PostOutputError(error.what());
  }
  written.push_back(out / "metrics.h5");
}

/// The run's PNGs (those of its SceneKind, and conservation.png when drawn), appended to `written`.
void draw_run_plots(const fs::path& out, const PostOptions& options, std::vector<fs::path>& written) {
  const SceneKind kind = options.scene_kind.value_or(
      options.potential.kind == PotentialSettings::Kind::self ? SceneKind::aggregate : SceneKind::deposit);
  const std::string arguments = kind == SceneKind::aggregate ? " --scene aggregate" : " --scene deposit";
  if (!post_detail::run_plots("run", arguments, out, options.plot, options.log, options.warnings)) return;
  post_detail::add_plot_files(out, run_plot_files(kind), written, options.warnings);
  if (fs::exists(out / "conservation.png")) written.push_back(out / "conservation.png");
}

}  // namespace

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
  post_detail::create_output_directory(out);
  std::vector<fs::path> written;
  std::int64_t grains = 0;
  for (std::size_t i = 0; i < model.body_count(); ++i) grains += model.is_grain(i) ? 1 : 0;

  const RunSeries series = reader.read_series();
  post_detail::check_series(run_file, series);
  written.push_back(write_series_csv(out / "series.csv", series, grains));

  // Metrics of every chosen snapshot, the impulse distribution of the last one, VTK on request.
  const double h = options.time_step > 0.0 ? options.time_step : reader.time_step();
  // A run with [[inflow]] (its first snapshot has bodies not in play): each snapshot's bodies in
  // play, whose model the VTK series follows (vtk_output.hpp).
  const bool inflow = reader.snapshot_count() > 0 && reader.read_snapshot(0).bodies_in_play < model.body_count();
  Model in_play;
  if (inflow) in_play = model;
  std::unique_ptr<VtkSeries> vtk;
  if (options.write_vtk) {
    vtk = std::make_unique<VtkSeries>(out / "vtk", inflow ? in_play : model, VtkSeriesOptions{h, 0.0, {}});
  }
  const SnapshotMetrics metrics =
      compute_snapshot_metrics(reader, run_file, options, inflow ? &in_play : nullptr, vtk.get());
  write_metrics_files(out, run_file, metrics, written);
  if (vtk) {
    for (const fs::path& collection : vtk->collections()) written.push_back(collection);
  }
  if (options.plots) draw_run_plots(out, options, written);
  if (options.log != nullptr) {
    for (const fs::path& path : written) *options.log << "  " << path.string() << "\n";
  }
  return written;
}

}  // namespace rubble
