// post_process_run / post_process_study on a run file written by RunFile here (no `rubble run`,
// no plots): the metrics CSV holds the chosen snapshots with the chain's known Z = 2 - 2/N.
#include "postprocessing/post.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <sstream>

#include "postprocessing/run_file.hpp"

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
  {
    const std::array<std::string_view, 1> stages{"all"};
    RunFile file = RunFile::create(run, model, "", stages);
    for (int k = 0; k < 6; ++k) {
      const std::array<double, 1> seconds{0.0};
      SeriesRow row;
      row.step = k + 1;
      row.time = 0.1 * (k + 1);
      row.stage_seconds = seconds;
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
  post_process_study({dir}, study);  // finds run.h5, skips post/metrics.h5
  const auto study_rows = read_csv(dir / "study" / "study.csv");
  ASSERT_EQ(study_rows.size(), 2u);
  EXPECT_EQ(study_rows[1][1], "spheres");
  EXPECT_EQ(std::stod(study_rows[1][2]), n);
  EXPECT_EQ(std::stod(study_rows[1][3]), 0.4);
  EXPECT_EQ(study_rows[1][4], "2");
  EXPECT_DOUBLE_EQ(std::stod(study_rows[1][6]), 2.0 - 2.0 / n);
  EXPECT_THROW(post_process_study({dir / "post"}, study), std::runtime_error);  // no run file there
}

}  // namespace
}  // namespace rubble
