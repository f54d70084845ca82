// The restart paths of simulation/run.cpp: a run resumed from any of its checkpoints, or stopped
// by the stop flag and resumed, ends bit for bit where the uninterrupted run ends, with the same
// run file series and snapshots; numerical failures name the step, the body and the stage and
// leave the checkpoints intact.
#include "simulation/run.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "postprocessing/run_reader.hpp"
#include "simulation/scene_file.hpp"

namespace rubble {
namespace {

namespace fs = std::filesystem;

// Twelve spheres falling into an open box under gravity: contacts, friction and warm starts
// within the 400 steps (impacts start around step 150).
constexpr const char* scene_text = R"(
name = "restart"
seed = 7
[time]
dt = 1e-4
end_time = 0.04
[gravity]
type = "uniform"
acceleration = [0.0, 0.0, -9.81]
[output]
snapshot_every_steps = 25
progress_interval = 1000.0
[[materials]]
name = "glass"
density = 2500.0
[[contact_laws]]
materials = ["glass", "glass"]
friction = 0.4
restitution = 0.2
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
[[generators]]
type = "box_deposit"
count = 12
radius_min = 0.02
radius_max = 0.03
region_min = [-0.1, -0.1, 0.0]
region_max = [0.1, 0.1, 0.2]
velocity = [0.3, 0.0, -1.0]
)";

Scene scene_in(const std::string& name) {
  Scene scene = parse_scene(scene_text, "restart.toml");
  scene.run.output.directory =
      (fs::temp_directory_path() / ("rubble_test_run_" + name + "_" + std::to_string(::getpid()))).string();
  fs::remove_all(scene.run.output.directory);
  return scene;
}

RunControl control_for() {
  RunControl control;
  control.scene_text = scene_text;
  control.scene_source = "restart.toml";
  control.checkpoint_interval = 0.0;  // by step count only: reproducible
  return control;
}

/// Reads what must not depend on interruptions: every series column but the wall times, and
/// every snapshot's state hash and contact impulses.
struct RunRecord {
  RunSeries series;
  std::vector<std::uint64_t> snapshot_hashes;
  std::vector<std::int64_t> snapshot_steps;
};
RunRecord read_record(const fs::path& file) {
  const RunReader reader = RunReader::open(file);
  RunRecord record;
  record.series = reader.read_series();
  for (std::size_t k = 0; k < reader.snapshot_count(); ++k) {
    const RunSnapshot snapshot = reader.read_snapshot(k);
    record.snapshot_hashes.push_back(state_hash(snapshot.state));
    record.snapshot_steps.push_back(snapshot.state.step);
  }
  return record;
}
/// The number of data sets listed by a ParaView collection (.pvd), and their times.
std::vector<double> pvd_times(const fs::path& pvd) {
  std::ifstream in(pvd);
  std::vector<double> times;
  std::string line;
  while (std::getline(in, line)) {
    const auto at = line.find("timestep=\"");
    if (at != std::string::npos) times.push_back(std::stod(line.substr(at + 10)));
  }
  return times;
}

void expect_same_record(const RunRecord& a, const RunRecord& b) {
  EXPECT_EQ(a.series.step, b.series.step);
  EXPECT_EQ(a.series.time, b.series.time);
  EXPECT_EQ(a.series.kinetic_energy, b.series.kinetic_energy);
  EXPECT_EQ(a.series.contacts, b.series.contacts);
  EXPECT_EQ(a.series.iterations, b.series.iterations);
  EXPECT_EQ(a.series.residual, b.series.residual);
  EXPECT_EQ(a.snapshot_steps, b.snapshot_steps);
  EXPECT_EQ(a.snapshot_hashes, b.snapshot_hashes);
}

TEST(Restart, FromEveryCheckpointEndsBitIdentical) {
  const Scene reference_scene = scene_in("reference");
  const RunSummary reference = run_scene(reference_scene, control_for());
  ASSERT_EQ(reference.final_step, 400);
  const RunRecord reference_record = read_record(reference.run_file);
  ASSERT_EQ(reference_record.series.step.size(), 400u);
  ASSERT_GT(reference_record.series.contacts.back(), 0) << "the scene must have contacts to test the warm start";

  // A run that kept a checkpoint every 40 steps; its run file, complete, is what a run killed
  // after its last checkpoint leaves (and more: every later row must be cut away on resume).
  const Scene scene = scene_in("checkpointed");
  RunControl control = control_for();
  control.checkpoint_every_steps = 40;
  control.checkpoints_kept = 100;
  const RunSummary full = run_scene(scene, control);
  EXPECT_EQ(full.state_hash, reference.state_hash);
  const std::vector<fs::path> checkpoints = list_checkpoints(checkpoint_folder(scene.run.output.directory));
  ASSERT_EQ(checkpoints.size(), 10u);

  for (const fs::path& file : checkpoints) {
    const Checkpoint checkpoint = read_checkpoint(file);
    SCOPED_TRACE(file.filename().string());
    const Scene resumed_scene = [&] {
      Scene s = parse_scene(checkpoint.scene_text, checkpoint.scene_source);
      s.run.output.directory = scene.run.output.directory;
      return s;
    }();
    RunControl resume = control;
    resume.resume = &checkpoint;
    const RunSummary summary = run_scene(resumed_scene, resume);
    EXPECT_EQ(summary.first_step, checkpoint.state.step);
    EXPECT_EQ(summary.state_hash, reference.state_hash);
    EXPECT_EQ(summary.mean_iterations, reference.mean_iterations);
    EXPECT_EQ(summary.max_residual, reference.max_residual);
    expect_same_record(read_record(summary.run_file), reference_record);
  }
}

// rubble run hands the scene's initial state to run_scene instead of a copy (one state less in
// memory): the run must be the one of run_scene(scene), record for record.
TEST(RunScene, FromTheMovedInitialStateIsTheSameRun) {
  const RunSummary reference = run_scene(scene_in("copied_state"), control_for());
  Scene scene = scene_in("moved_state");
  State initial = std::move(scene.state);
  scene.state = State{};  // run_scene must not read it
  const RunSummary moved = run_scene(scene, std::move(initial), control_for());
  EXPECT_EQ(moved.final_step, reference.final_step);
  EXPECT_EQ(moved.state_hash, reference.state_hash);
  expect_same_record(read_record(moved.run_file), read_record(reference.run_file));
}

TEST(Restart, StopFlagWritesACheckpointAndResumesIdentically) {
  const RunSummary reference = run_scene(scene_in("stop_reference"), control_for());
  const Scene scene = scene_in("stop");
  RunControl control = control_for();
  const std::atomic<int> stop{15};  // as if SIGTERM came during the first step
  control.stop_requested = &stop;
  const RunSummary stopped = run_scene(scene, control);
  EXPECT_TRUE(stopped.interrupted);
  EXPECT_EQ(stopped.final_step, 1);
  ASSERT_FALSE(stopped.last_checkpoint.empty());

  const LoadedCheckpoint loaded = load_newest_checkpoint(checkpoint_folder(scene.run.output.directory));
  EXPECT_EQ(loaded.checkpoint.state.step, 1);
  {
    // The state at the stop is also the run file's last snapshot (the initial one, then step 1),
    // and the file says why the run ended.
    const RunReader reader = RunReader::open(stopped.run_file);
    EXPECT_EQ(reader.status(), "interrupted");
    ASSERT_EQ(reader.snapshot_count(), 2u);
    const RunSnapshot last = reader.read_snapshot(1);
    EXPECT_EQ(last.state.step, 1);
    EXPECT_EQ(state_hash(last.state), state_hash(loaded.checkpoint.state));
    EXPECT_EQ(state_hash(last.state), stopped.state_hash);
  }
  RunControl resume = control_for();
  resume.resume = &loaded.checkpoint;
  const RunSummary finished = run_scene(scene, resume);
  EXPECT_FALSE(finished.interrupted);
  EXPECT_EQ(finished.state_hash, reference.state_hash);
  // The snapshot of the stop is gone (step 1 is off the 25-step cadence): the same file as the
  // uninterrupted run's.
  expect_same_record(read_record(finished.run_file), read_record(reference.run_file));
  EXPECT_EQ(RunReader::open(finished.run_file).status(), "end_time");
}

// [output] vtk = true: the ParaView series is written during the run, one entry per snapshot of
// the run file (17 here: step 0 and every 25 steps to 400), also across a stop and a resume (the
// stop's own snapshot is replaced by the resumed run's next ones).
TEST(RunScene, VtkTrueWritesTheParaViewSeriesWithTheSnapshots) {
  Scene scene = scene_in("vtk");
  scene.run.output.write_vtk = true;
  RunControl control = control_for();
  const std::atomic<int> stop{2};  // as if SIGINT came during the first step
  control.stop_requested = &stop;
  const RunSummary stopped = run_scene(scene, control);
  const fs::path vtk = fs::path(scene.run.output.directory) / "vtk";
  EXPECT_EQ(pvd_times(vtk / "spheres.pvd"), (std::vector<double>{0.0, 1e-4}));

  const LoadedCheckpoint loaded = load_newest_checkpoint(checkpoint_folder(scene.run.output.directory));
  RunControl resume = control_for();
  resume.resume = &loaded.checkpoint;
  const RunSummary finished = run_scene(scene, resume);
  EXPECT_EQ(finished.snapshots, 17);
  const RunReader reader = RunReader::open(finished.run_file);
  std::vector<double> snapshot_times;
  for (std::size_t k = 0; k < reader.snapshot_count(); ++k)
    snapshot_times.push_back(reader.read_snapshot(k).state.time);
  for (const char* kind : {"spheres", "contacts", "walls"}) {
    SCOPED_TRACE(kind);
    const std::vector<double> times = pvd_times(vtk / (std::string(kind) + ".pvd"));
    ASSERT_EQ(times.size(), 17u);
    for (std::size_t k = 0; k < times.size(); ++k) EXPECT_NEAR(times[k], snapshot_times[k], 1e-12);
    for (std::size_t k = 0; k < times.size(); ++k) {
      char name[32];
      std::snprintf(name, sizeof name, "%s_%06zu.vtp", kind, k);
      EXPECT_TRUE(fs::exists(vtk / name)) << name;
    }
  }
  EXPECT_FALSE(fs::exists(vtk / "polyhedra.pvd"));  // no polyhedra in the scene
}

TEST(Restart, LongerEndTimeExtendsTheRunWithTheSameSnapshotCadence) {
  Scene scene = scene_in("extend");
  scene.run.output.snapshot_every_steps = 0;  // 100 snapshots per run: the period comes from the first session
  scene.run.end_time = 0.02;                  // 200 steps: period 2
  const RunSummary first = run_scene(scene, control_for());
  EXPECT_EQ(first.snapshots, 101);
  const LoadedCheckpoint loaded = load_newest_checkpoint(checkpoint_folder(scene.run.output.directory));
  EXPECT_EQ(loaded.checkpoint.progress.snapshot_period, 2);
  scene.run.end_time = 0.04;
  RunControl resume = control_for();
  resume.resume = &loaded.checkpoint;
  const RunSummary extended = run_scene(scene, resume);
  EXPECT_EQ(extended.final_step, 400);
  EXPECT_EQ(extended.snapshots, 201);  // still every 2 steps
}

// run.h5 is not needed to resume (issue 17): missing, or damaged (garbage bytes where the file
// was), the run goes on from the checkpoint in a new run.h5 (the damaged one set aside) and ends
// bit-identical; the new file opens with the checkpoint's state and holds the rows after it,
// equal to the reference run's rows for those steps.
TEST(Restart, ResumesWithoutAnIntactRunFile) {
  const RunSummary reference = run_scene(scene_in("no_file_reference"), control_for());
  const RunRecord reference_record = read_record(reference.run_file);
  for (const std::string damage : {"missing", "garbage"}) {
    SCOPED_TRACE(damage);
    Scene scene = scene_in("no_file_" + damage);
    scene.run.output.write_vtk = true;
    RunControl control = control_for();
    control.checkpoint_every_steps = 100;
    control.checkpoints_kept = 10;
    run_scene(scene, control);
    const fs::path directory = scene.run.output.directory;
    const fs::path checkpoint_file = checkpoint_folder(directory) / "step-000000000200.ckpt";
    const Checkpoint checkpoint = read_checkpoint(checkpoint_file);
    fs::remove(directory / "run.h5");
    fs::remove_all(directory / "vtk");  // lost with it: the series is rewritten from the checkpoint
    if (damage == "garbage") std::ofstream(directory / "run.h5") << "not an HDF5 file at all";
    std::ostringstream warnings;
    RunControl resume = control;
    resume.resume = &checkpoint;
    resume.warnings = &warnings;
    const RunSummary summary = run_scene(scene, resume);
    EXPECT_EQ(summary.state_hash, reference.state_hash);
    EXPECT_NE(warnings.str().find("cannot be reopened"), std::string::npos) << warnings.str();
    EXPECT_EQ(fs::exists(directory / "run.h5.damaged-at-step-200"), damage == "garbage");
    const RunRecord record = read_record(summary.run_file);
    ASSERT_EQ(record.series.step.size(), 200u);
    EXPECT_EQ(record.series.step.front(), 201);
    EXPECT_EQ(record.series.kinetic_energy.back(), reference_record.series.kinetic_energy.back());
    ASSERT_FALSE(record.snapshot_steps.empty());
    EXPECT_EQ(record.snapshot_steps.front(), 200);
    EXPECT_EQ(record.snapshot_hashes.back(), reference_record.snapshot_hashes.back());
    // The ParaView series starts again with the new run file: its entries are the file's snapshots.
    const std::vector<double> times = pvd_times(directory / "vtk" / "spheres.pvd");
    ASSERT_EQ(times.size(), record.snapshot_steps.size());
    EXPECT_NEAR(times.front(), 0.02, 1e-12);
    EXPECT_TRUE(fs::exists(directory / "vtk" / "spheres_000000.vtp"));
  }
}

TEST(Restart, ACheckpointOfAnotherSceneIsRefused) {
  const Scene scene = scene_in("mismatch");
  run_scene(scene, control_for());
  Checkpoint checkpoint = load_newest_checkpoint(checkpoint_folder(scene.run.output.directory)).checkpoint;
  checkpoint.state.resize(3);
  RunControl resume = control_for();
  resume.resume = &checkpoint;
  EXPECT_THROW(run_scene(scene, resume), CheckpointError);
}

// Self-gravity evaluated every 3 steps ([gravity] evaluate_every): the field held between
// evaluations is saved in the checkpoint, so a run resumed at step 40 (field evaluated at step 39)
// uses the same field for steps 40 and 41 and ends bit for bit where the uninterrupted run ends.
// Control: the same resume without the held field (evaluated afresh at step 40) ends elsewhere,
// so the test can tell. G = 0.5 makes the grains' mutual pull ~10 m/s^2, like the lab's g.
TEST(Restart, HeldSelfGravityFieldSurvivesTheCheckpoint) {
  std::string text = scene_text;
  const std::string uniform = "type = \"uniform\"\nacceleration = [0.0, 0.0, -9.81]";
  text.replace(text.find(uniform), uniform.size(), "type = \"direct\"\nG = 0.5\nevaluate_every = 3");
  const auto make_scene = [&](const std::string& name) {
    Scene scene = parse_scene(text, "restart-held.toml");
    scene.run.output.directory =
        (fs::temp_directory_path() / ("rubble_test_run_" + name + "_" + std::to_string(::getpid()))).string();
    fs::remove_all(scene.run.output.directory);
    return scene;
  };
  RunControl control = control_for();
  control.scene_text = text;
  control.scene_source = "restart-held.toml";
  const Scene reference_scene = make_scene("held_reference");
  ASSERT_EQ(reference_scene.run.step.gravity.evaluate_every, 3);
  const RunSummary reference = run_scene(reference_scene, control);

  const Scene scene = make_scene("held");
  RunControl checkpointed = control;
  checkpointed.checkpoint_every_steps = 40;
  checkpointed.checkpoints_kept = 100;
  run_scene(scene, checkpointed);
  const fs::path at_40 = checkpoint_folder(scene.run.output.directory) / "step-000000000040.ckpt";
  const Checkpoint checkpoint = read_checkpoint(at_40);
  EXPECT_EQ(checkpoint.carry.held_gravity_step, 39);
  ASSERT_EQ(checkpoint.carry.held_gravity.size(), checkpoint.state.body_count());

  RunControl resume = checkpointed;
  resume.resume = &checkpoint;
  EXPECT_EQ(run_scene(scene, resume).state_hash, reference.state_hash);

  Checkpoint without_field = checkpoint;
  without_field.carry.held_gravity.clear();
  without_field.carry.held_gravity_step = -1;
  resume.resume = &without_field;
  EXPECT_NE(run_scene(scene, resume).state_hash, reference.state_hash);
}

/// Runs `scene` and returns the NumericalFailure's message ("" if none).
std::string failure_of(const Scene& scene, const RunControl& control) {
  try {
    run_scene(scene, control);
  } catch (const NumericalFailure& e) {
    return e.what();
  }
  return "";
}

TEST(NumericalFailure, RunawaySpeedNamesStepBodyStageAndKeepsTheCheckpoints) {
  const Scene scene = scene_in("runaway");
  RunControl control = control_for();
  control.checkpoint_every_steps = 10;
  // Every grain starts at (0.3, 0, -1) m/s (the generator's velocity) and falls freely:
  // |v|^2 = 0.09 + (1 + g t)^2 passes 1.1^2 at t = 5.94 ms, so the free velocity of step 60 is
  // the first over the bound, body 0 the first grain checked.
  control.max_speed = 1.1;
  const std::string message = failure_of(scene, control);
  EXPECT_NE(message.find("stage free_velocity"), std::string::npos) << message;
  EXPECT_NE(message.find("runaway speed"), std::string::npos) << message;
  EXPECT_NE(message.find("body 0"), std::string::npos) << message;
  EXPECT_NE(message.find("step "), std::string::npos) << message;
  const LoadedCheckpoint last = load_newest_checkpoint(checkpoint_folder(scene.run.output.directory));
  EXPECT_TRUE(last.rejected.empty());
  EXPECT_NE(message.find("step 60 "), std::string::npos) << message;
  EXPECT_EQ(last.checkpoint.state.step, 50);  // untouched by the failure
  EXPECT_NE(message.find("last checkpoint (step 50)"), std::string::npos) << message;
}

TEST(NumericalFailure, NonFiniteGravityIsTracedToTheExternalForces) {
  Scene scene = scene_in("nan_gravity");
  scene.run.step.gravity.acceleration.z() = std::numeric_limits<double>::quiet_NaN();
  const std::string message = failure_of(scene, control_for());
  EXPECT_NE(message.find("step 1 "), std::string::npos) << message;
  EXPECT_NE(message.find("stage external_forces"), std::string::npos) << message;
  EXPECT_NE(message.find("last checkpoint (none)"), std::string::npos) << message;
}

TEST(NumericalFailure, NonFiniteVelocityIsTracedToTheFreeVelocity) {
  Scene scene = scene_in("nan_velocity");
  scene.state.velocity[3].x() = std::numeric_limits<double>::infinity();
  const std::string message = failure_of(scene, control_for());
  EXPECT_NE(message.find("stage free_velocity: body 3"), std::string::npos) << message;
}

TEST(NumericalFailure, DefaultBoundIsTheBoundingRadiusPerStep) {
  Scene scene = scene_in("radius_bound");
  // 0.03 m / 1e-4 s = 300 m/s at most for the largest grain; 1000 m/s is caught at step 1.
  scene.state.velocity[5] = Vec3(0.0, 1000.0, 0.0);
  const std::string message = failure_of(scene, control_for());
  EXPECT_NE(message.find("body 5: free velocity: runaway speed"), std::string::npos) << message;
  RunControl unchecked = control_for();
  unchecked.max_speed = -1.0;  // disabled: the grain flies off through the open side
  scene.run.end_time = 0.001;
  EXPECT_EQ(failure_of(scene, unchecked), "");
}

// Most steps stopping at the sweep cap is said once, on the warnings stream, with the count and
// the largest residual; a run whose solves converge says nothing. The spheres land from step ~200
// of 400: with one sweep a step and an unreachable tolerance, every step with contacts is capped.
TEST(RunScene, WarnsOnceWhenMostStepsStopAtTheSweepCap) {
  Scene capped = scene_in("sweep_cap");
  capped.run.step.solver.max_iterations = 1;
  capped.run.step.solver.tolerance = 1e-14;
  std::ostringstream warnings;
  RunControl control = control_for();
  control.warnings = &warnings;
  const RunSummary summary = run_scene(capped, control);
  EXPECT_GE(summary.unconverged_steps, 150);
  const std::string text = warnings.str();
  const std::string expected =
      "of the last 100 steps stopped at the sweep cap ([solver] max_iterations = 1) short of the tolerance";
  const auto at = text.find(expected);
  ASSERT_NE(at, std::string::npos) << text;
  EXPECT_EQ(text.find(expected, at + 1), std::string::npos) << "said more than once: " << text;

  Scene converging = scene_in("sweep_cap_default");
  std::ostringstream quiet;
  control.warnings = &quiet;
  const RunSummary converged = run_scene(converging, control);
  EXPECT_EQ(converged.unconverged_steps, 0);
  EXPECT_EQ(quiet.str(), "");
}

}  // namespace
}  // namespace rubble
