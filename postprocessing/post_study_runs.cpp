// post_process_study, first half: the run files collected and each reduced to a StudyRun (its
// grains, the window t >= stable_after averaged over, the <E_c>(t) curve, whether it is included).
#include <algorithm>
#include <memory>
#include <optional>
#include <ostream>
#include <stdexcept>
#include <tuple>

#include "postprocessing/post_detail.hpp"
#include "postprocessing/post_study.hpp"
#include "postprocessing/run_reader.hpp"

namespace rubble::post_detail {
namespace {

namespace fs = std::filesystem;

/// Sets the run's shape family ("spheres", "polyhedra", "mixed"), n_s and mu: the mean friction
/// coefficient over the grains' material pairs (one pair in the study).
void describe_grains(const Model& model, StudyRun& r) {
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
  r.friction = pairs > 0 ? r.friction / pairs : 0.0;
  r.shape = polyhedra == 0 ? "spheres" : spheres == 0 ? "polyhedra" : "mixed";
  r.grains = spheres + polyhedra;
}

/// Every snapshot's metrics (grain sizes once per run); the last one also with the run's gravity,
/// for the escape test (an O(N^2) direct sum, so not at every snapshot).
std::vector<AggregateMetrics> every_snapshot_metrics(const RunReader& reader, const fs::path& run,
                                                     const PotentialSettings& potential) {
  const Model& model = reader.model();
  const GrainSizes sizes = grain_sizes(model);
  std::vector<AggregateMetrics> all;
  Model in_play;  // a run with [[inflow]]: the bodies in play of the snapshot (the others not inserted yet)
  for (std::size_t k = 0; k < reader.snapshot_count(); ++k) {
    RunSnapshot snapshot = reader.read_snapshot(k);
    const bool all_in_play = snapshot.bodies_in_play == model.body_count();
    if (!all_in_play) {
      snapshot.state = state_prefix(snapshot.state, snapshot.bodies_in_play);
      if (in_play.body_count() != snapshot.bodies_in_play) in_play = model_prefix(model, snapshot.bodies_in_play);
    }
    check_snapshot(run, k, snapshot.state);
    const bool last = k + 1 == reader.snapshot_count();
    all.push_back(compute_metrics(all_in_play ? model : in_play, sizes, snapshot.state, snapshot.contacts,
                                  last ? potential : PotentialSettings{}));
    check_metrics(run, k, metrics_row(all.back()));
  }
  return all;
}

/// The window t >= stable_after (the paper's stabilised regime), never replaced: a run that did
/// not reach it is reported at its final snapshot, flagged, and left out by default. Sets the
/// averages, their spread and the deepest overlap over the window, and the last snapshot's counts.
void average_window(const std::vector<AggregateMetrics>& all, double stable_after, StudyRun& r) {
  r.end_time = all.back().time;
  r.detached = static_cast<double>(all.back().detached_grains);
  r.escaping = static_cast<double>(all.back().escaping_grains);
  std::vector<const AggregateMetrics*> window;
  for (const AggregateMetrics& m : all) {
    if (m.time >= stable_after) window.push_back(&m);
  }
  r.reached_window = !window.empty();
  if (!r.reached_window) window.push_back(&all.back());
  r.averaged_over = r.reached_window ? "window" : "final_snapshot";
  r.snapshots_used = window.size();
  for (const auto& [name, field] : averaged_metrics()) {
    std::vector<double> values;
    values.reserve(window.size());
    for (const AggregateMetrics* m : window) values.push_back(field(*m));
    r.values[name] = spread(values);
  }
  for (const AggregateMetrics* m : window) r.max_overlap = std::max(r.max_overlap, m->max_overlap);
}

/// <E_c>(t) from the per-step series: peak, plateau over the window, the curve (thinned to ~2000
/// points, the peak kept) for the overlay plot, and the rest time of a run that ended at rest.
void add_energy_curve(const RunSeries& series, double stable_after, StudyRun& r) {
  if (series.time.empty() || !(r.grains > 0)) return;
  const auto peak = static_cast<std::size_t>(
      std::max_element(series.kinetic_energy.begin(), series.kinetic_energy.end()) - series.kinetic_energy.begin());
  r.peak_time = series.time[peak];
  r.peak_energy = series.kinetic_energy[peak] / r.grains;
  std::vector<double> plateau;
  const std::size_t stride = std::max<std::size_t>(1, series.time.size() / 2000);
  for (std::size_t k = 0; k < series.time.size(); ++k) {
    if (series.time[k] >= stable_after) plateau.push_back(series.kinetic_energy[k] / r.grains);
    if (k % stride == 0 || k == peak || k + 1 == series.time.size()) {
      r.energy_time.push_back(series.time[k]);
      r.energy.push_back(series.kinetic_energy[k] / r.grains);
    }
  }
  if (!plateau.empty()) r.plateau = spread(plateau).mean;
  if (r.at_rest) r.rest_time = series.time.back();
}

/// The solver's accuracy over the window: steps that stopped at the sweep cap, and the largest
/// residual a step ended with. A run at the cap for much of the window holds its grains with
/// impulses short of the tolerance; its window values are then as good as that residual.
void count_capped_steps(const RunSeries& series, double stable_after, StudyRun& r) {
  for (std::size_t k = 0; k < series.time.size(); ++k) {
    if (series.time[k] < stable_after) continue;
    ++r.window_steps;
    if (r.solver.max_iterations > 0 && series.iterations[k] >= r.solver.max_iterations) ++r.capped_steps;
    if (std::isnan(r.max_residual) || series.residual[k] > r.max_residual) r.max_residual = series.residual[k];
  }
}

/// Warns when steps of the window stopped at the sweep cap.
void warn_capped_steps(const StudyOptions& options, const StudyRun& r) {
  if (r.capped_steps == 0 || options.warnings == nullptr) return;
  *options.warnings << "rubble post: study: " << r.path << ": " << r.capped_steps << " of the " << r.window_steps
                    << " steps in the window stopped at the sweep cap (" << r.solver.max_iterations
                    << " sweeps; residual up to " << significant(r.max_residual) << " against the tolerance "
                    << parameter_text(r.solver.tolerance)
                    << "): its window values are as accurate as that residual (study.csv capped_steps)\n";
}

/// Whether the run takes part in the fits and plots: it ran to its end (at rest, or at its end
/// time: the paper's runs, too, ran to a fixed time past the window) and reached the window. A
/// run cut short (a signal, a failure, still running) or short of the window is added to
/// `left_out` with the reason, and warned about.
void decide_inclusion(const StudyOptions& options, StudyRun& r, std::vector<std::string>& left_out) {
  const bool ran_to_end = r.at_rest || r.status == "end_time";
  r.included = (ran_to_end && r.reached_window) || options.include_unfinished;
  if (ran_to_end && r.reached_window) return;
  std::string why = !ran_to_end ? "did not end at rest or at its end time (status " + r.status + ")" : "";
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

/// One run file reduced to its StudyRun; nullopt (with a note in the log) when it is not a run
/// file (folders also hold metrics.h5 and other HDF5 files) or holds no snapshot.
std::optional<StudyRun> reduce_run(const fs::path& run, const StudyOptions& options,
                                   std::vector<std::string>& left_out) {
  std::unique_ptr<RunReader> reader;
  try {
    reader = std::make_unique<RunReader>(RunReader::open(run));
  } catch (const std::runtime_error& e) {
    if (options.log != nullptr) *options.log << "rubble post: skipping " << e.what() << "\n";
    return std::nullopt;
  }
  if (reader->snapshot_count() == 0) {
    if (options.log != nullptr) *options.log << "rubble post: skipping " << run.string() << ": no snapshot\n";
    return std::nullopt;
  }
  StudyRun r;
  r.path = run.string();
  r.status = reader->status();
  r.at_rest = r.status == "at_rest";
  describe_grains(reader->model(), r);
  const StudyRunSettings settings = options.settings_of ? options.settings_of(*reader) : StudyRunSettings{};
  r.solver = settings.solver;
  average_window(every_snapshot_metrics(*reader, run, settings.potential), options.stable_after, r);
  const RunSeries series = reader->read_series();
  check_series(run, series);
  add_energy_curve(series, options.stable_after, r);
  count_capped_steps(series, options.stable_after, r);
  decide_inclusion(options, r, left_out);
  warn_capped_steps(options, r);
  if (options.log != nullptr) {
    *options.log << "rubble post: study: " << r.path << " (" << r.shape << ", n_s = " << r.grains
                 << ", mu = " << parameter_text(r.friction) << ", " << r.snapshots_used << " snapshots in the "
                 << (r.reached_window ? "window" : "final state") << ")\n";
  }
  return r;
}

}  // namespace

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

std::vector<AveragedMetric> averaged_metrics() {
  return {
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
}

std::vector<fs::path> collect_run_files(const std::vector<fs::path>& inputs) {
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
  return runs;
}

StudyRuns reduce_runs(const std::vector<fs::path>& runs, const StudyOptions& options) {
  StudyRuns study;
  for (const fs::path& run : runs) {
    if (std::optional<StudyRun> r = reduce_run(run, options, study.left_out)) study.runs.push_back(std::move(*r));
  }
  // Rows by shape, mu, n_s (then path: seeds side by side), the order a reader compares them in.
  std::stable_sort(study.runs.begin(), study.runs.end(), [](const StudyRun& a, const StudyRun& b) {
    return std::tie(a.shape, a.friction, a.grains, a.path) < std::tie(b.shape, b.friction, b.grains, b.path);
  });
  return study;
}

}  // namespace rubble::post_detail
