// simulation/branch.cpp: a branch (rubble run SCENE --from RUN_DIR) starts from the saved run's
// contacts as its warm start, rescaled to its own dt, so that a deposit at rest stays at rest
// from the first step instead of being solved again from zero impulses.
#include "simulation/branch.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <sstream>

#include "postprocessing/metrics.hpp"
#include "postprocessing/run_reader.hpp"
#include "simulation/run.hpp"
#include "simulation/scene_file.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;

/// 27 spheres dropped into an open box (friction 0.3, dt = 2 ms), run until at rest.
std::string deposit_text() {
  std::ifstream in(fs::path(RUBBLE_SOURCE_DIR) / "tests/apps/inputs/branch_deposit.toml");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

fs::path fresh_directory(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / ("rubble_test_branch_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

RunControl quiet_control(const std::string& text) {
  RunControl control;
  control.scene_text = text;
  control.scene_source = "branch_deposit.toml";
  control.checkpoint_interval = 0.0;
  return control;
}

/// The deposit poured to rest once; its folder holds the final checkpoint.
const fs::path& settled_deposit() {
  static const fs::path dir = [] {
    const std::string text = deposit_text();
    Scene scene = parse_scene(text, "branch_deposit.toml");
    // Poured with plain sweeps: with the default over-relaxation the pour comes to rest in
    // another state, where a grain still settles in the branch's sixth and seventh steps, which
    // take three sweeps whatever the branch's relaxation (measured; an event of the deposit, not
    // of the warm start this file tests). The branches below run with the default.
    scene.run.step.solver.relaxation = 1.0;
    fs::path out = fresh_directory("pour");
    scene.run.output.directory = out.string();
    const RunSummary summary = run_scene(scene, quiet_control(text));
    EXPECT_TRUE(summary.reached_rest) << "the 27-sphere deposit did not come to rest";
    return out;
  }();
  return dir;
}

/// NLGS sweeps of each step of a 10-step (or 11-step) branch of the settled deposit with time step `dt`,
/// warm-started from `warm_start`, and its largest kinetic energy.
struct BranchRun {
  std::vector<std::int64_t> sweeps;
  double peak_kinetic_energy = 0.0;
};
BranchRun run_branch(const std::string& name, double dt, ContactList warm_start) {
  const std::string text = deposit_text();
  Scene scene = parse_scene(text, "branch_deposit.toml");
  const SavedState saved = load_saved_state(parse_branch_source(settled_deposit().string()));
  scene.state = saved.state;
  scene.run.step.integrator.time_step = dt;
  scene.run.until_rest = false;
  scene.run.end_time = saved.state.time + 10.5 * dt;  // 10 or 11 steps (the count runs from t = 0)
  scene.run.output.directory = fresh_directory(name).string();
  State initial_state = scene.state;
  run_scene(scene, std::move(initial_state), std::move(warm_start), quiet_control(text));
  const RunSeries series = RunReader::open(fs::path(scene.run.output.directory) / "run.h5").read_series();
  BranchRun run;
  run.sweeps.assign(series.iterations.begin(), series.iterations.end());
  for (const double e : series.kinetic_energy) run.peak_kinetic_energy = std::max(run.peak_kinetic_energy, e);
  return run;
}

TEST(BranchWarmStart, TheCheckpointsContactsScaledByTheRatioOfTheTimeSteps) {
  const SavedState saved = load_saved_state(parse_branch_source(settled_deposit().string()));
  ASSERT_GT(saved.contacts.size(), 27u);  // every grain rests on something
  EXPECT_EQ(saved.time_step, 0.002);
  const ContactList same = branch_warm_start(saved, 0.002);
  const ContactList half = branch_warm_start(saved, 0.001);
  ASSERT_EQ(same.size(), saved.contacts.size());
  ASSERT_EQ(half.size(), saved.contacts.size());
  for (std::size_t k = 0; k < saved.contacts.size(); ++k) {
    EXPECT_EQ(same[k].id, saved.contacts[k].id);
    EXPECT_EQ(same[k].impulse, saved.contacts[k].impulse);
    EXPECT_EQ(half[k].impulse, 0.5 * saved.contacts[k].impulse);  // a power of two: exact
  }
}

TEST(BranchWarmStart, FromASnapshotThereIsNone) {
  const SavedState saved = load_saved_state(parse_branch_source(settled_deposit().string() + ":snapshot=-1"));
  EXPECT_TRUE(saved.contacts.empty());
  EXPECT_TRUE(branch_warm_start(saved, 0.002).empty());
}

// The deposit at rest (by its scene's criterion; one sphere still rolls on the floor):
// warm-started, the branch's steps meet the tolerance in a sweep, at its own dt or at half of it,
// and the kinetic energy stays that of the saved state within 1 %; solved from zero impulses, the
// first step needs many more sweeps.
TEST(BranchWarmStart, KeepsASettledDepositAtRestFromTheFirstStep) {
  const SavedState saved = load_saved_state(parse_branch_source(settled_deposit().string()));
  const double saved_energy = kinetic_energy(saved.model, saved.state);
  const BranchRun warm = run_branch("warm", 0.002, branch_warm_start(saved, 0.002));
  const BranchRun warm_half_dt = run_branch("warm_half", 0.001, branch_warm_start(saved, 0.001));
  const BranchRun cold = run_branch("cold", 0.002, {});
  ASSERT_GE(warm.sweeps.size(), 10u);
  ASSERT_GE(warm_half_dt.sweeps.size(), 10u);
  ASSERT_GE(cold.sweeps.size(), 10u);
  for (const std::int64_t sweeps : warm.sweeps) EXPECT_EQ(sweeps, 1);
  for (const std::int64_t sweeps : warm_half_dt.sweeps) EXPECT_EQ(sweeps, 1);
  EXPECT_GE(cold.sweeps.front(), 10);
  EXPECT_LT(warm.peak_kinetic_energy, 1.01 * saved_energy);
  EXPECT_LT(warm_half_dt.peak_kinetic_energy, 1.01 * saved_energy);
}

}  // namespace
}  // namespace rubble
