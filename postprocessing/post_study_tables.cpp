// post_process_study, second half: the tables written from the reduced runs (study.csv,
// study_fits.csv, study_kinetic_energy.csv, study.txt) and the study's PNGs.
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <ostream>
#include <set>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "postprocessing/post.hpp"
#include "postprocessing/post_detail.hpp"
#include "postprocessing/post_study.hpp"

namespace rubble {
namespace post_detail {
namespace {

namespace fs = std::filesystem;

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

/// Grain diameters do not change during a run: no spread column for them.
bool has_spread(const std::string& name) { return name != "mean_diameter" && name != "equivalent_diameter"; }

/// study.csv's header: the run's description, then each averaged metric and its spread.
std::vector<std::string> study_csv_header() {
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
  for (const auto& [name, field] : averaged_metrics()) {
    header.push_back(name);
    if (has_spread(name)) header.push_back(name + "_spread");
  }
  header.insert(header.end(), {"max_overlap", "max_overlap_over_mean_d", "detached_grains", "escaping_grains",
                               "window_steps", "capped_steps", "max_window_residual"});
  return header;
}

/// The run's row of study.csv, in study_csv_header's order.
std::vector<std::string> study_csv_row(const StudyRun& r, const StudyOptions& options) {
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
  for (const auto& [name, field] : averaged_metrics()) {
    row.push_back(significant(r.values.at(name).mean));
    if (has_spread(name)) row.push_back(significant(r.values.at(name).deviation));
  }
  row.insert(row.end(),
             {significant(r.max_overlap), significant(r.max_overlap / r.values.at("mean_diameter").mean),
              count_text(r.detached), count_text(r.escaping), std::to_string(r.window_steps),
              r.solver.max_iterations > 0 ? std::to_string(r.capped_steps) : "", significant(r.max_residual)});
  return row;
}

/// The (shape, mu) series of the included runs, in the table's order.
std::vector<std::pair<std::string, double>> fitted_series(const std::vector<StudyRun>& study) {
  std::vector<std::pair<std::string, double>> series;
  for (const StudyRun& r : study) {
    if (r.included && std::find(series.begin(), series.end(), std::pair{r.shape, r.friction}) == series.end()) {
      series.emplace_back(r.shape, r.friction);
    }
  }
  return series;
}

/// Throws std::runtime_error, naming the runs left out and why, when no run is included.
void require_included_runs(const StudyRuns& study, const StudyOptions& options) {
  const auto used = std::count_if(study.runs.begin(), study.runs.end(), [](const StudyRun& r) { return r.included; });
  if (used != 0) return;
  std::string message =
      "rubble post --study: no run file with snapshots that ended at rest or at its end time in the window t >= " +
      parameter_text(options.stable_after) + " s found in the given paths";
  if (!study.left_out.empty()) {
    message += "; " + std::to_string(study.left_out.size()) + " left out:";
    for (const std::string& run : study.left_out) message += " " + run;
    message += " (--include-unfinished includes them; --stable-after sets the window)";
  }
  message += " (study.csv lists every run)";
  throw std::runtime_error(message);
}

}  // namespace

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

std::string parameter_text(double x) {
  std::array<char, 32> text{};
  std::snprintf(text.data(), text.size(), "%.6g", x);
  return text.data();
}

std::string count_text(double x) { return std::to_string(std::llround(x)); }

fs::path write_study_csv(const fs::path& out, const std::vector<StudyRun>& study, const StudyOptions& options) {
  fs::path path = out / "study.csv";
  CsvWriter csv(path, study_csv_header());
  for (const StudyRun& r : study) csv.text_row(study_csv_row(r, options));
  csv.close();
  return path;
}

fs::path write_study_fits(const fs::path& out, const std::vector<StudyRun>& study) {
  // Power-law fits y = a n_s^b per (shape, mu) series of the included runs (every run a point, so
  // seeds weigh as runs), by least squares on the logarithms; the peak <E_c> also as an
  // exponential y = a exp(b n_s), on log y, to weigh the paper's "exponential" against a power law.
  fs::path path = out / "study_fits.csv";
  CsvWriter csv(path,
                {"shape", "friction", "quantity", "model", "prefactor", "exponent", "points", "rms_log_residual"});
  for (const auto& [shape, friction] : fitted_series(study)) {
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
  return path;
}

fs::path write_study_means(const fs::path& out, const std::vector<StudyRun>& study) {
  // Each run's window mean is one sample: the spread is the seeds' (n - 1 in the denominator),
  // not the window's, which study.csv gives per run.
  using RunValue = double (*)(const StudyRun&);
  const std::vector<std::pair<std::string, RunValue>> quantities{
      {"Z_max", [](const StudyRun& r) { return r.values.at("Z_max").mean; }},
      {"Z_without_rattlers", [](const StudyRun& r) { return r.values.at("Z_without_rattlers").mean; }},
      {"packing_fraction", [](const StudyRun& r) { return r.values.at("packing_fraction").mean; }},
      {"inertia_packing_fraction", [](const StudyRun& r) { return r.values.at("inertia_packing_fraction").mean; }},
      {"D_max_over_mean_d", [](const StudyRun& r) { return r.values.at("D_max_over_mean_d").mean; }},
      {"D_max_over_d_star", [](const StudyRun& r) { return r.values.at("D_max_over_d_star").mean; }},
      {"peak_mean_kinetic_energy", [](const StudyRun& r) { return r.peak_energy; }},
      {"peak_time", [](const StudyRun& r) { return r.peak_time; }},
      {"plateau_mean_kinetic_energy", [](const StudyRun& r) { return r.plateau; }},
  };
  std::vector<std::string> header{"shape", "friction", "grains", "runs"};
  for (const auto& [name, value] : quantities) {
    header.push_back(name);
    header.push_back(name + "_spread");
  }
  fs::path path = out / "study_means.csv";
  CsvWriter csv(path, header);
  std::set<std::tuple<std::string, double, double>> written;
  for (const StudyRun& first : study) {  // the table's order: shape, mu, n_s
    if (!first.included || !written.insert({first.shape, first.friction, first.grains}).second) continue;
    std::vector<const StudyRun*> seeds;
    for (const StudyRun& r : study) {
      if (r.included && r.shape == first.shape && r.friction == first.friction && r.grains == first.grains) {
        seeds.push_back(&r);
      }
    }
    std::vector<std::string> row{first.shape, parameter_text(first.friction), count_text(first.grains),
                                 std::to_string(seeds.size())};
    for (const auto& [name, value] : quantities) {
      std::vector<double> samples;
      samples.reserve(seeds.size());
      for (const StudyRun* r : seeds) samples.push_back(value(*r));
      const Spread over_seeds = spread(samples);
      row.push_back(significant(over_seeds.mean));
      row.push_back(significant(over_seeds.deviation));
    }
    csv.text_row(row);
  }
  csv.close();
  return path;
}

fs::path write_study_kinetic_energy(const fs::path& out, const std::vector<StudyRun>& study) {
  fs::path path = out / "study_kinetic_energy.csv";
  CsvWriter csv(path, {"row", "time", "mean_kinetic_energy"});
  for (std::size_t k = 0; k < study.size(); ++k) {
    for (std::size_t j = 0; j < study[k].energy.size(); ++j) {
      csv.row({static_cast<double>(k), study[k].energy_time[j], study[k].energy[j]});
    }
  }
  csv.close();
  return path;
}

fs::path write_study_text(const fs::path& out, const std::vector<StudyRun>& study, const StudyOptions& options) {
  fs::path path = out / "study.txt";
  std::ofstream text(path);
  if (!text) throw PostOutputError(path.string() + ": cannot create the file: " + std::strerror(errno));
  std::array<char, 512> line{};
  std::snprintf(line.data(), line.size(),
                "Window: t >= %s s (%s min). Values: mean over the window's snapshots; runs marked * did not "
                "reach the window (final snapshot shown), ! were cut short (neither at rest nor at their end "
                "time); both are left out of the fits and plots unless --include-unfinished. rest_min -: the "
                "run did not stop at rest. cap%%: of the window's steps, those that stopped at the solver's "
                "sweep cap (their impulses short of the tolerance).\n",
                parameter_text(options.stable_after).c_str(), parameter_text(options.stable_after / 60.0).c_str());
  text << line.data();
  std::snprintf(line.data(), line.size(), "%-9s %6s %6s %2s %8s %8s %9s %6s %6s %6s %6s %8s %8s %9s %5s %5s %5s\n",
                "shape", "n_s", "mu", "", "peak_min", "rest_min", "plateau_J", "Z", "Z_nr", "nu", "nu_I", "D/<d>",
                "D/d*", "overlap/d", "det", "esc", "cap%");
  text << line.data();
  for (const StudyRun& r : study) {
    const bool ran_to_end = r.at_rest || r.status == "end_time";
    const std::string flag = std::string(r.reached_window ? "" : "*") + (ran_to_end ? "" : "!");
    const std::string capped = r.solver.max_iterations > 0 && r.window_steps > 0
                                   ? std::to_string(std::llround(100.0 * static_cast<double>(r.capped_steps) /
                                                                 static_cast<double>(r.window_steps)))
                                   : "-";
    std::snprintf(line.data(), line.size(), "%-9s %6s %6s %2s %8s %8s %9s %6s %6s %6s %6s %8s %8s %9s %5s %5s %5s\n",
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
                  count_text(r.detached).c_str(), count_text(r.escaping).c_str(), capped.c_str());
    text << line.data();
  }
  text.close();
  if (!text) throw PostOutputError(path.string() + ": cannot write the file: " + std::strerror(errno));
  if (options.log != nullptr) {
    std::ifstream back(path);
    *options.log << back.rdbuf();
  }
  return path;
}

}  // namespace post_detail

std::vector<std::filesystem::path> post_process_study(const std::vector<std::filesystem::path>& inputs,
                                                      const StudyOptions& options) {
  const std::vector<std::filesystem::path> runs = post_detail::collect_run_files(inputs);
  const std::filesystem::path out = options.output_directory;
  post_detail::create_output_directory(out);
  const post_detail::StudyRuns study = post_detail::reduce_runs(runs, options);
  std::vector<std::filesystem::path> written{post_detail::write_study_csv(out, study.runs, options)};
  post_detail::require_included_runs(study, options);  // study.csv is written all the same
  written.push_back(post_detail::write_study_fits(out, study.runs));
  written.push_back(post_detail::write_study_means(out, study.runs));
  written.push_back(post_detail::write_study_kinetic_energy(out, study.runs));
  written.push_back(post_detail::write_study_text(out, study.runs, options));
  if (options.plots && post_detail::run_plots("study", "", out, options.plot, options.log, options.warnings)) {
    post_detail::add_plot_files(out,
                                {"study_kinetic_energy.png", "study_coordination.png", "study_diameter.png",
                                 "study_packing.png", "study_peak_energy.png"},
                                written, options.warnings);
  }
  return written;
}

}  // namespace rubble
