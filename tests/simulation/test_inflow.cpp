// Tests of [[inflow]] (simulation/inflow.hpp): a pour inserts its grains at the rate (grain k at
// start + k / rate, so rate x t grains by time t, within one grain), never where they would
// overlap a grain or a wall, the same on one thread and two, and a run resumed from a checkpoint
// taken mid-pour ends bit for bit where the uninterrupted run ends.
#include "simulation/inflow.hpp"

#include <gtest/gtest.h>
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "postprocessing/metrics.hpp"
#include "postprocessing/post.hpp"
#include "postprocessing/run_reader.hpp"
#include "simulation/run.hpp"
#include "simulation/scene_file.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;

// An open box (floor and four sides, 0.2 m wide) fed from a region above its floor: 60 grains,
// a mix of spheres and random polyhedra, at 2000 grains/s from t = 5 ms, thrown down at 1 m/s.
// The pour lasts 29.5 ms (steps 50 to 345); the grains reach the floor and touch each other.
constexpr const char* pour_text = R"(
name = "pour"
seed = 3
[time]
dt = 1e-4
end_time = 0.05
[gravity]
type = "uniform"
acceleration = [0.0, 0.0, -9.81]
[output]
snapshot_every_steps = 20
progress_interval = 1000.0
[[materials]]
name = "sand"
density = 2600.0
[[contact_laws]]
materials = ["sand", "sand"]
friction = 0.5
restitution = 0.1
[[walls]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[walls]]
type = "plane"
point = [-0.1, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
[[walls]]
type = "plane"
point = [0.1, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
[[walls]]
type = "plane"
point = [0.0, -0.1, 0.0]
normal = [0.0, 1.0, 0.0]
[[walls]]
type = "plane"
point = [0.0, 0.1, 0.0]
normal = [0.0, -1.0, 0.0]
[[inflow]]
count = 60
rate = 2000.0
start_time = 0.005
shape = "mix"
polyhedron_fraction = 0.3
min_vertices = 8
max_vertices = 12
radius_min = 0.01
radius_max = 0.015
region_min = [-0.09, -0.09, 0.01]
region_max = [0.09, 0.09, 0.15]
velocity = [0.0, 0.0, -1.0]
)";

constexpr double rate = 2000.0;
constexpr double start = 0.005;
constexpr std::size_t count = 60;
constexpr std::size_t walls = 5;

Scene pour_scene(const std::string& name) {
  Scene scene = parse_scene(pour_text, "pour.toml");
  scene.run.output.directory =
      (fs::temp_directory_path() / ("rubble_test_inflow_" + name + "_" + std::to_string(::getpid()))).string();
  fs::remove_all(scene.run.output.directory);
  return scene;
}

RunControl control_for() {
  RunControl control;
  control.scene_text = pour_text;
  control.scene_source = "pour.toml";
  control.checkpoint_interval = 0.0;  // by step count only: reproducible
  return control;
}

/// Bodies of a snapshot before the first one not in play (NaN position).
std::size_t bodies_in_play(const State& state) {
  std::size_t n = 0;
  while (n < state.body_count() && state.position[n].allFinite()) ++n;
  return n;
}

TEST(Inflow, GrainsAreTheLastBodiesDueAtTheRate) {
  const Scene scene = pour_scene("plan");
  const InflowPlan& plan = scene.inflow;
  ASSERT_EQ(plan.first_body, walls);  // no grain of its own, then the five walls
  ASSERT_EQ(plan.grains.size(), count);
  ASSERT_EQ(scene.model.body_count(), walls + count);
  for (std::size_t b = walls; b < scene.model.body_count(); ++b) EXPECT_TRUE(scene.model.is_grain(b));
  EXPECT_EQ(plan.due_count(0.0), 0u);
  EXPECT_EQ(plan.due_count(start), 1u);
  // Closed form: floor((t - start) rate) + 1 grains are due by t, all of them after the last.
  for (const double t : {0.0051, 0.0123, 0.02, 0.0344, 0.04}) {
    const auto expected = std::min<std::size_t>(count, static_cast<std::size_t>(std::floor((t - start) * rate)) + 1);
    EXPECT_EQ(plan.due_count(t), expected) << "t = " << t;
  }
}

// mass_rate instead of rate: grains per second = mass_rate / the mean mass of the inflow's grains,
// here taken from the model (its own masses, from density and volume).
TEST(Inflow, MassRateSetsTheGrainRateFromTheMeanGrainMass) {
  std::string text = pour_text;
  const std::string rate_line = "rate = 2000.0";
  text.replace(text.find(rate_line), rate_line.size(), "mass_rate = 20.0");
  const Scene scene = parse_scene(text, "pour.toml");
  double mass = 0.0;
  for (std::size_t b = walls; b < scene.model.body_count(); ++b) mass += scene.model.mass[b];
  const double grain_rate = 20.0 / (mass / static_cast<double>(count));
  ASSERT_GT(grain_rate, 500.0);  // about 20 g a grain: about 10^3 grains/s
  for (const double t : {0.0101, 0.023, 0.047, 0.09}) {
    const auto expected =
        std::min<std::size_t>(count, static_cast<std::size_t>(std::floor((t - start) * grain_rate)) + 1);
    EXPECT_EQ(scene.inflow.due_count(t), expected) << "t = " << t;
  }
}

TEST(Inflow, PourInsertsRateTimesTimeGrains) {
  const Scene scene = pour_scene("rate");
  const RunSummary summary = run_scene(scene, control_for());
  ASSERT_EQ(summary.final_step, 500);
  const RunReader reader = RunReader::open(summary.run_file);
  ASSERT_EQ(reader.snapshot_count(), 26u);  // step 0 and every 20 steps
  const double h = scene.run.step.integrator.time_step;
  for (std::size_t k = 0; k < reader.snapshot_count(); ++k) {
    const State state = reader.read_snapshot(k).state;
    SCOPED_TRACE("snapshot " + std::to_string(k) + ", t = " + std::to_string(state.time));
    ASSERT_EQ(state.body_count(), walls + count);
    const std::size_t placed = bodies_in_play(state) - walls;
    for (std::size_t b = walls + placed; b < state.body_count(); ++b) EXPECT_TRUE(std::isnan(state.position[b].x()));
    // Grains enter before a step, at its start time: the snapshot after the step ending at t
    // holds those due by t - h (none at the first snapshot, written before any step).
    EXPECT_EQ(placed, state.step == 0 ? 0u : scene.inflow.due_count(state.time - h));
    // Within one grain of rate x (t - start) (and one step's worth, rate h = 0.2 grain).
    const double expected = std::clamp((state.time - start) * rate, 0.0, static_cast<double>(count));
    EXPECT_LE(std::abs(static_cast<double>(placed) - expected), 1.0 + rate * h);
  }
  EXPECT_EQ(bodies_in_play(reader.read_snapshot(reader.snapshot_count() - 1).state), walls + count);
  const RunSeries series = reader.read_series();
  EXPECT_GT(series.contacts.back(), 0) << "the grains must touch: the resume test checks the warm start";
}

// The run file of a pour: the documented layout (check_run_file.py, layout only: the snapshot
// attributes @bodies_in_play, @inflow_placed, @inflow_waiting are documented as "Only with
// [[inflow]]") and, read by h5py, counts that agree with the NaN rows.
TEST(Inflow, RunFileHasTheDocumentedCounts) {
  const Scene scene = pour_scene("run_file");
  const RunSummary summary = run_scene(scene, control_for());
  const std::string layout = std::string("/usr/bin/python3 ") + RUBBLE_CHECK_RUN_FILE_SCRIPT + " " +
                             summary.run_file.string() + " - " + RUBBLE_SOURCE_DIR + "/docs/output-format.md";
  EXPECT_EQ(std::system(layout.c_str()), 0) << layout;
  const std::string counts = std::string("/usr/bin/python3 -c '\n") +
                             "import sys, h5py, numpy as np\n"
                             "f = h5py.File(sys.argv[1], \"r\")\n"
                             "for name, s in f[\"snapshots\"].items():\n"
                             "    finite = int(np.isfinite(s[\"position\"][:, 0]).sum())\n"
                             "    assert s.attrs[\"bodies_in_play\"] == finite, (name, finite)\n"
                             "    assert s.attrs[\"inflow_placed\"] == finite - 5, name\n"
                             "    assert s.attrs[\"inflow_waiting\"] == 0, name\n"
                             "assert finite == 65\n"
                             "' " +
                             summary.run_file.string();
  EXPECT_EQ(std::system(counts.c_str()), 0) << counts;
}

// rubble post on a pour: each snapshot's metrics over the grains in play (not the NaN rows of the
// grains still to come), and the ParaView series of those grains.
TEST(Inflow, PostProcessesThePourSnapshotBySnapshot) {
  const Scene scene = pour_scene("post");
  const RunSummary summary = run_scene(scene, control_for());
  PostOptions options;
  options.output_directory = fs::path(scene.run.output.directory) / "post";
  options.plots = false;
  options.write_vtk = true;
  ASSERT_NO_THROW(post_process_run(summary.run_file, options));
  const RunReader reader = RunReader::open(summary.run_file);
  std::ifstream csv(options.output_directory / "metrics.csv");
  std::vector<std::vector<std::string>> rows;
  for (std::string line; std::getline(csv, line);) {
    std::vector<std::string> cells;
    std::stringstream stream(line);
    for (std::string cell; std::getline(stream, cell, ',');) cells.push_back(cell);
    rows.push_back(cells);
  }
  const std::vector<std::string> names = metrics_column_names();
  ASSERT_EQ(rows.size(), reader.snapshot_count() + 1);  // the header, then one row per snapshot
  ASSERT_EQ(rows[0], names);
  const auto grains = static_cast<std::size_t>(std::find(names.begin(), names.end(), "grains") - names.begin());
  for (std::size_t k = 0; k < reader.snapshot_count(); ++k) {
    EXPECT_EQ(std::stod(rows[k + 1][grains]), static_cast<double>(reader.read_snapshot(k).bodies_in_play - walls))
        << "snapshot " << k;
  }
  EXPECT_TRUE(fs::exists(options.output_directory / "vtk" / "spheres.pvd"));
}

/// The overlap of ball (x, r) with body b of the state (its bounding ball, or a plane wall's
/// half-space), m; > 0 means they overlap.
double overlap(const Model& model, const State& state, std::size_t b, const Vec3& x, double r) {
  if (model.is_grain(b)) return r + model.bounding_radius[b] - (x - state.position[b]).norm();
  const Vec3 normal = state.orientation[b] * model.planes[static_cast<std::size_t>(model.shape_index[b])].normal;
  return r - normal.dot(x - state.position[b]);
}

// Every grain, when inserted, checked against every body in play then (all pairs); a region too
// full to take them all keeps the rest waiting, in order, and says which grain is blocked.
TEST(Inflow, InsertedGrainsOverlapNothingAndWaitWhenTheRegionIsFull) {
  Scene scene = pour_scene("overlap");
  // All due at once in a small region: room for some only.
  InflowPlan plan = scene.inflow;
  plan.inflows[0].region_min = Vec3(-0.03, -0.03, 0.02);
  plan.inflows[0].region_max = Vec3(0.03, 0.03, 0.05);
  Model in_play = model_prefix(scene.model, plan.first_body);
  State state = state_prefix(scene.state, plan.first_body);
  state.time = 1.0;
  std::size_t checked = 0;
  InflowInsertion last;
  for (int pass = 0; pass < 3; ++pass, ++state.step) {
    const std::size_t before = in_play.body_count();
    last = insert_due_grains(plan, scene.model, in_play, state);
    ASSERT_EQ(in_play.body_count(), before + last.placed);
    ASSERT_EQ(state.body_count(), in_play.body_count());
    for (std::size_t g = before; g < in_play.body_count(); ++g) {
      const double r = in_play.bounding_radius[g];
      EXPECT_EQ(r, scene.model.bounding_radius[g]);
      EXPECT_EQ(state.velocity[g], Vec3(0.0, 0.0, -1.0));
      for (int axis = 0; axis < 3; ++axis) {
        EXPECT_GE(state.position[g][axis], plan.inflows[0].region_min[axis]);
        EXPECT_LE(state.position[g][axis], plan.inflows[0].region_max[axis]);
      }
      for (std::size_t b = 0; b < g; ++b) {
        EXPECT_LE(overlap(in_play, state, b, state.position[g], r), 0.0) << "grain body " << g << " vs body " << b;
        ++checked;
      }
    }
  }
  EXPECT_GT(in_play.body_count(), walls + 5);
  EXPECT_GT(last.waiting, 0u) << "the small region must fill up";
  EXPECT_EQ(last.waiting, walls + count - in_play.body_count());
  EXPECT_EQ(last.blocked_body, in_play.body_count());
  EXPECT_GT(checked, 50u);
}

TEST(Inflow, SamePourOnOneAndTwoThreads) {
  const int previous = omp_get_max_threads();
  omp_set_num_threads(1);
  const RunSummary one = run_scene(pour_scene("one_thread"), control_for());
  omp_set_num_threads(2);
  const RunSummary two = run_scene(pour_scene("two_threads"), control_for());
  omp_set_num_threads(previous);
  EXPECT_EQ(one.state_hash, two.state_hash);
  EXPECT_EQ(one.mean_iterations, two.mean_iterations);
}

TEST(Inflow, ResumedMidPourEndsBitIdentical) {
  const RunSummary reference = run_scene(pour_scene("reference"), control_for());
  const Scene scene = pour_scene("checkpointed");
  RunControl control = control_for();
  control.checkpoint_every_steps = 100;
  control.checkpoints_kept = 100;
  const RunSummary full = run_scene(scene, control);
  EXPECT_EQ(full.state_hash, reference.state_hash);
  const std::vector<fs::path> checkpoints = list_checkpoints(checkpoint_folder(scene.run.output.directory));
  ASSERT_EQ(checkpoints.size(), 5u);
  const RunReader reference_file = RunReader::open(reference.run_file);
  for (const fs::path& file : checkpoints) {
    const Checkpoint checkpoint = read_checkpoint(file);
    SCOPED_TRACE(file.filename().string());
    RunControl resume = control;
    resume.resume = &checkpoint;
    const RunSummary summary = run_scene(scene, resume);
    EXPECT_EQ(summary.first_step, checkpoint.state.step);
    EXPECT_EQ(summary.state_hash, reference.state_hash);
    const RunReader resumed = RunReader::open(summary.run_file);
    ASSERT_EQ(resumed.snapshot_count(), reference_file.snapshot_count());
    for (std::size_t k = 0; k < resumed.snapshot_count(); ++k) {
      const State a = resumed.read_snapshot(k).state, b = reference_file.read_snapshot(k).state;
      EXPECT_EQ(bodies_in_play(a), bodies_in_play(b));
      EXPECT_EQ(state_prefix(a, bodies_in_play(a)).position, state_prefix(b, bodies_in_play(b)).position);
    }
  }
  // Mid-pour: the checkpoints of steps 100 to 300 hold part of the grains only.
  const Checkpoint middle = read_checkpoint(checkpoints[checkpoints.size() - 2]);  // newest first
  ASSERT_EQ(middle.state.step, 200);
  EXPECT_GT(middle.state.body_count(), walls);
  EXPECT_LT(middle.state.body_count(), walls + count);
}

}  // namespace
}  // namespace rubble
