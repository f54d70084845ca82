// post_process_run / post_process_study on a run file written by RunFile here (no `rubble run`,
// no plots): the metrics CSV holds the chosen snapshots with the chain's known Z = 2 - 2/N.
#include "postprocessing/post.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <iterator>
#include <sstream>

#include "postprocessing/run_file.hpp"
#include "postprocessing/run_reader.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;

std::vector<std::vector<std::string>> read_csv(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream stream(line);
    std::string cell;
    while (std::getline(stream, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

TEST(Post, MetricsOfChosenSnapshotsAndStudy) {
  const fs::path dir = fs::path(::testing::TempDir()) / "rubble_test_post";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const int n = 5;
  Model model;
  model.materials = {{"rock", 1000.0}};
  model.contact_laws.reset(1, ContactLaw{0.4, 0.0});
  State state;
  for (int i = 0; i < n; ++i) add_sphere(model, 0.5, 0);
  state.resize(n);
  ContactList chain;
  for (int i = 0; i < n; ++i) state.position[static_cast<std::size_t>(i)] = Vec3(i, 0.0, 0.0);
  for (int i = 0; i + 1 < n; ++i) {
    Contact c;
    c.id = {static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(i + 1), 0, 0};
    c.frame = frame_from_normal(Vec3::UnitX());
    c.impulse = Vec3(1e-3, 0.0, 0.0);
    chain.push_back(c);
  }
  const fs::path run = dir / "run.h5";
  // The same run three times: ended at rest, stopped by a signal, and run to its end time (in
  // subfolders).
  fs::create_directories(dir / "stopped");
  fs::create_directories(dir / "until_end");
  for (const auto& [path, status] :
       {std::pair{run, RunStatus::at_rest}, std::pair{dir / "stopped" / "run.h5", RunStatus::interrupted},
        std::pair{dir / "until_end" / "run.h5", RunStatus::end_time}}) {
    const std::array<std::string_view, 1> stages{"all"};
    RunFile file = RunFile::create(path, model, "", stages);
    file.set_status(status);
    for (int k = 0; k < 6; ++k) {
      const std::array<double, 1> seconds{0.0};
      SeriesRow row;
      row.step = k + 1;
      row.time = 0.1 * (k + 1);
      row.stage_seconds = seconds;
      // The last step (in the window t >= 0.45 below) stopped at a sweep cap of 50.
      row.iterations = k == 5 ? 50 : 7;
      row.residual = k == 5 ? 3e-4 : 5e-5;
      file.append_series(row);
      state.time = row.time;
      state.step = row.step;
      file.write_snapshot(state, chain);
    }
  }
  PostOptions options;
  options.output_directory = dir / "post";
  options.every = 4;  // snapshots 0 and 4, and the last (5)
  options.plots = false;
  const auto written = post_process_run(run, options);
  EXPECT_EQ(written.size(), 4u);  // series.csv, metrics.csv, impulse_distribution.csv, metrics.h5
  const auto rows = read_csv(dir / "post" / "metrics.csv");
  ASSERT_EQ(rows.size(), 4u);  // header + 3
  const std::vector<std::string> names = metrics_column_names();
  EXPECT_EQ(rows[0], names);
  const auto column = [&](const std::string& name) {
    return static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
  };
  EXPECT_EQ(std::stod(rows[1][column("step")]), 1.0);
  EXPECT_EQ(std::stod(rows[2][column("step")]), 5.0);
  EXPECT_EQ(std::stod(rows[3][column("step")]), 6.0);
  EXPECT_DOUBLE_EQ(std::stod(rows[3][column("coordination")]), 2.0 - 2.0 / n);

  StudyOptions study;
  study.output_directory = dir / "study";
  study.plots = false;
  study.stable_after = 0.45;  // snapshots at t = 0.5 and 0.6
  study.settings_of = [](const RunReader&) { return StudyRunSettings{{}, SolverLimits{50, 1e-4}}; };
  std::ostringstream study_warnings;
  study.warnings = &study_warnings;
  post_process_study({dir}, study);  // finds the three run.h5, skips post/metrics.h5
  auto study_rows = read_csv(dir / "study" / "study.csv");
  ASSERT_EQ(study_rows.size(), 4u);
  const auto cell = [&](std::size_t row, const std::string& name) {
    const auto& header = study_rows[0];
    const auto at = std::find(header.begin(), header.end(), name);
    EXPECT_NE(at, header.end()) << name;
    return at == header.end() ? std::string() : study_rows[row].at(static_cast<std::size_t>(at - header.begin()));
  };
  EXPECT_EQ(cell(1, "run"), run.string());
  EXPECT_EQ(cell(1, "status"), "at_rest");
  EXPECT_EQ(cell(1, "reached_window"), "1");
  EXPECT_EQ(cell(1, "included"), "1");
  EXPECT_EQ(cell(1, "shape"), "spheres");
  EXPECT_EQ(std::stod(cell(1, "grains")), n);
  EXPECT_EQ(std::stod(cell(1, "friction")), 0.4);
  EXPECT_EQ(cell(1, "averaged_over"), "window");
  EXPECT_EQ(cell(1, "snapshots_used"), "2");
  // Printed at 4 significant digits (a window mean, not a 17-digit number).
  EXPECT_EQ(cell(1, "Z_max"), "1.600");  // the chain: 2 - 2/N
  EXPECT_EQ(cell(1, "Z_max_spread"), "0");
  EXPECT_EQ(cell(1, "rest_time"), "0.6000");         // the run's end, at rest
  EXPECT_EQ(cell(1, "D_max_over_mean_d"), "5.000");  // 5 unit spheres in a row
  EXPECT_EQ(cell(1, "detached_grains"), "0");
  // One of the window's two steps stopped at the sweep cap: counted, its residual shown, warned about.
  EXPECT_EQ(cell(1, "window_steps"), "2");
  EXPECT_EQ(cell(1, "capped_steps"), "1");
  EXPECT_EQ(cell(1, "max_window_residual"), "3.000e-04");
  EXPECT_NE(study_warnings.str().find(run.string() + ": 1 of the 2 steps in the window stopped at the sweep cap (50 "
                                                     "sweeps; residual up to 3.000e-04 against the tolerance 0.0001)"),
            std::string::npos)
      << study_warnings.str();
  // The stopped run is listed with its status and left out of the plots; no rest time.
  EXPECT_EQ(cell(2, "status"), "interrupted");
  EXPECT_EQ(cell(2, "included"), "0");
  EXPECT_EQ(cell(2, "rest_time"), "");
  // The run to its end time, past the window, counts (the paper's runs ran to a fixed time); it
  // has no rest time and the same window means as the run at rest.
  EXPECT_EQ(cell(3, "run"), (dir / "until_end" / "run.h5").string());
  EXPECT_EQ(cell(3, "status"), "end_time");
  EXPECT_EQ(cell(3, "included"), "1");
  EXPECT_EQ(cell(3, "rest_time"), "");
  EXPECT_EQ(cell(3, "Z_max"), "1.600");
  EXPECT_TRUE(fs::exists(dir / "study" / "study.txt"));
  EXPECT_TRUE(fs::exists(dir / "study" / "study_fits.csv"));
  // The seeds' table: one parameter set, the two included runs (at rest, to its end time), whose
  // window means agree, so no spread.
  const auto means = read_csv(dir / "study" / "study_means.csv");
  ASSERT_EQ(means.size(), 2u);
  const auto mean_cell = [&](const std::string& name) {
    const auto at = std::find(means[0].begin(), means[0].end(), name);
    EXPECT_NE(at, means[0].end()) << name;
    return at == means[0].end() ? std::string() : means[1].at(static_cast<std::size_t>(at - means[0].begin()));
  };
  EXPECT_EQ(mean_cell("shape"), "spheres");
  EXPECT_EQ(mean_cell("grains"), "5");
  EXPECT_EQ(mean_cell("runs"), "2");
  EXPECT_EQ(mean_cell("Z_max"), "1.600");
  EXPECT_EQ(mean_cell("Z_max_spread"), "0");
  EXPECT_EQ(mean_cell("D_max_over_mean_d"), "5.000");
  EXPECT_TRUE(fs::exists(dir / "study" / "study_kinetic_energy.csv"));
  std::ifstream study_text(dir / "study" / "study.txt");
  const std::string table((std::istreambuf_iterator<char>(study_text)), std::istreambuf_iterator<char>());
  EXPECT_NE(table.find("  cap%\n"), std::string::npos) << table;
  EXPECT_NE(table.find("    50\n"), std::string::npos) << table;  // 1 of 2 steps: 50 %
  // Without the solver's settings nothing is counted as capped (not "0": unknown).
  study.settings_of = nullptr;
  post_process_study({dir}, study);
  study_rows = read_csv(dir / "study" / "study.csv");
  EXPECT_EQ(cell(1, "capped_steps"), "");
  EXPECT_EQ(cell(1, "max_window_residual"), "3.000e-04");
  study.include_unfinished = true;
  post_process_study({dir}, study);
  study_rows = read_csv(dir / "study" / "study.csv");
  ASSERT_EQ(study_rows.size(), 4u);
  EXPECT_EQ(cell(2, "included"), "1");
  // Only unfinished runs: nothing to plot, unless asked.
  study.include_unfinished = false;
  try {
    post_process_study({dir / "stopped"}, study);
    ADD_FAILURE() << "expected an error: no run ended at rest";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("did not end at rest"), std::string::npos) << error.what();
  }
  // A window no run reaches is never replaced by another: the run at rest is reported at its
  // final snapshot, flagged, and left out (the paper's t > 125 min against a run stopped earlier).
  study.stable_after = 1.0;
  try {
    post_process_study({run}, study);
    ADD_FAILURE() << "expected an error: no run reached the window";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("did not reach the window"), std::string::npos) << error.what();
  }
  study_rows = read_csv(dir / "study" / "study.csv");
  ASSERT_EQ(study_rows.size(), 2u);
  EXPECT_EQ(cell(1, "reached_window"), "0");
  EXPECT_EQ(cell(1, "included"), "0");
  EXPECT_EQ(cell(1, "averaged_over"), "final_snapshot");
  EXPECT_EQ(cell(1, "snapshots_used"), "1");
  EXPECT_EQ(cell(1, "plateau_mean_kinetic_energy"), "");
  study.stable_after = 0.45;
  EXPECT_THROW(post_process_study({dir / "post"}, study), std::runtime_error);  // no run file there
}

// Plots are a convenience: without a Python that has matplotlib, post_process_run writes the CSV
// and HDF5 files, warns, and succeeds.
TEST(Post, PlotsWithoutMatplotlibAreAWarningNotAnError) {
  const fs::path dir = fs::path(::testing::TempDir()) / "rubble_test_post_no_matplotlib";
  fs::remove_all(dir);
  fs::create_directories(dir);
  Model model;
  model.materials = {{"rock", 1000.0}};
  model.contact_laws.reset(1, ContactLaw{0.4, 0.0});
  add_sphere(model, 0.5, 0);
  State state;
  state.resize(1);
  {
    const std::array<std::string_view, 1> stages{"all"};
    RunFile file = RunFile::create(dir / "run.h5", model, "", stages);
    file.write_snapshot(state, {});
  }
  // A "Python" that cannot import matplotlib (false always fails).
  std::ostringstream warnings;
  PostOptions options;
  options.output_directory = dir / "post";
  options.plot.python = "false";
  options.warnings = &warnings;
  const auto written = post_process_run(dir / "run.h5", options);
  EXPECT_EQ(written.size(), 4u);  // series.csv, metrics.csv, impulse_distribution.csv, metrics.h5
  EXPECT_TRUE(fs::exists(dir / "post" / "metrics.csv"));
  EXPECT_FALSE(fs::exists(dir / "post" / "kinetic_energy.png"));
  EXPECT_NE(warnings.str().find("plots not drawn: no Python with matplotlib (tried false)"), std::string::npos)
      << warnings.str();
}

}  // namespace
}  // namespace rubble
