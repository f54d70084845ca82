// Tests of the scene reader (simulation/scene_file.cpp, scene_reader.cpp, scene_sections.cpp,
// scene_checks.cpp): good scenes give the model, state and options they describe (masses against
// 4/3 pi r^3 rho), the [time] section's automatic step and rest criterion, and every file of the
// corpus bad/*.toml is rejected with a SceneError carrying the expected message, the file name and
// the line.
#include "simulation/run_control.hpp"
#include "simulation/scene_file.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <numbers>

#include "scene/scene_test_scenes.hpp"

namespace rubble {
namespace {

using scene_test::cloud_scene;
using scene_test::read_text;
using scene_test::two_grains_in_a_box;

TEST(ParseScene, GoodSceneGivesItsModelStateAndOptions) {
  const Scene scene = parse_scene(two_grains_in_a_box, "two.toml");
  EXPECT_EQ(scene.name, "two");
  EXPECT_EQ(scene.run.seed, 9u);
  EXPECT_EQ(scene.run.step.integrator.time_step, 2e-4);
  EXPECT_EQ(scene.run.step.integrator.theta, 0.75);
  EXPECT_EQ(scene.run.end_time, 0.5);
  EXPECT_EQ(scene.run.step.solver.tolerance, 1e-6);
  EXPECT_EQ(scene.run.step.solver.max_iterations, 200);
  EXPECT_EQ(scene.run.step.solver.relaxation, 0.9);
  EXPECT_FALSE(scene.run.step.solver.warm_start);
  EXPECT_EQ(scene.run.step.solver.overlap_recovery.fraction, 0.5);
  EXPECT_EQ(scene.run.step.solver.overlap_recovery.max_velocity, 0.25);
  EXPECT_EQ(scene.run.step.solver.polish_after, 15);
  EXPECT_EQ(scene.run.step.solver.polish_iterations, 7);
  EXPECT_EQ(scene.run.step.solver.polish_max_contacts, 700u);
  EXPECT_EQ(scene.run.step.detection.alert_distance, 0.001);
  EXPECT_EQ(scene.run.step.detection.pair_list_margin, 0.002);
  EXPECT_EQ(scene.run.step.gravity.kind, GravitySettings::Kind::uniform);
  EXPECT_EQ(scene.run.step.gravity.acceleration, Vec3(0, 0, -9.81));
  EXPECT_EQ(scene.run.output.directory, "out");
  EXPECT_EQ(scene.run.output.snapshot_every_steps, 50);
  EXPECT_EQ(scene.run.output.progress_interval, 0.0);
  EXPECT_TRUE(scene.run.output.write_vtk);

  const Model& model = scene.model;
  ASSERT_EQ(model.body_count(), 4u);  // grains first, then walls, in file order
  ASSERT_EQ(model.materials.size(), 2u);
  EXPECT_EQ(model.materials[0].name, "rock");
  EXPECT_EQ(model.materials[0].density, 3000.0);
  EXPECT_EQ(model.contact_laws.get(0, 0).friction_coefficient, 0.5);
  EXPECT_EQ(model.contact_laws.get(0, 0).normal_restitution, 0.1);
  EXPECT_EQ(model.contact_laws.get(0, 1).friction_coefficient, 0.2);
  EXPECT_EQ(model.contact_laws.get(1, 0).normal_restitution, 0.0);  // default restitution

  EXPECT_EQ(model.shape_kind[0], ShapeKind::sphere);
  EXPECT_EQ(model.sphere_radius(0), 0.5);
  EXPECT_EQ(model.sphere_radius(1), 0.25);
  // m = rho 4/3 pi r^3, relative tolerance 1e-14 (round-off).
  EXPECT_NEAR(model.mass[0], 3000.0 * 4.0 / 3.0 * std::numbers::pi * 0.125, 1e-14 * model.mass[0]);
  EXPECT_NEAR(model.mass[1], 3000.0 * 4.0 / 3.0 * std::numbers::pi * 0.015625, 1e-14 * model.mass[1]);
  EXPECT_EQ(model.material[0], 0);
  EXPECT_EQ(model.shape_kind[2], ShapeKind::plane);
  EXPECT_TRUE(model.is_fixed(2));
  EXPECT_EQ(model.planes[0].normal, Vec3::UnitZ());  // normalised
  EXPECT_EQ(model.material[2], 1);
  EXPECT_EQ(model.shape_kind[3], ShapeKind::box);
  EXPECT_EQ(model.boxes[0].half_extents, Vec3(1, 2, 3));

  const State& state = scene.state;
  ASSERT_EQ(state.body_count(), 4u);
  EXPECT_EQ(state.time, 0.0);
  EXPECT_EQ(state.position[0], Vec3::Zero());
  EXPECT_EQ(state.velocity[0], Vec3(1, 2, 3));
  EXPECT_EQ(state.angular_velocity[0], Vec3(0.1, 0.2, 0.3));
  EXPECT_EQ(state.position[1], Vec3(2, 0, 0));
  EXPECT_EQ(state.velocity[1], Vec3::Zero());
  EXPECT_EQ(state.position[2], Vec3(0, 0, -1));
  EXPECT_EQ(state.position[3], Vec3(5, 0, 0));
  // [0, 0, 0, 2] normalised: a half turn about z.
  EXPECT_EQ(state.orientation[3].coeffs(), Quat(0, 0, 0, 1).coeffs());
}

TEST(ParseScene, OmittedTablesTakeTheirDocumentedDefaults) {
  const Scene scene = parse_scene(R"(
[time]
dt = 1e-3
end_time = 1
[[materials]]
name = "m"
density = 1000
[default_contact_law]
friction = 0.4
[[bodies]]
shape = "sphere"
radius = 1
position = [0, 0, 0]
)",
                                  "dir/minimal.toml");
  EXPECT_EQ(scene.name, "minimal");  // the file's stem
  EXPECT_EQ(scene.run.seed, 1u);
  EXPECT_EQ(scene.run.step.integrator.theta, 0.5);
  EXPECT_EQ(scene.run.step.gravity.kind, GravitySettings::Kind::none);
  const SolverOptions solver_defaults{};
  EXPECT_EQ(scene.run.step.solver.tolerance, solver_defaults.tolerance);
  EXPECT_EQ(scene.run.step.solver.max_iterations, solver_defaults.max_iterations);
  EXPECT_EQ(scene.run.step.detection.alert_distance, 0.0);
  EXPECT_EQ(scene.run.output.directory, OutputOptions{}.directory);
  EXPECT_EQ(scene.model.material[0], 0);  // the only material
  EXPECT_EQ(scene.model.contact_laws.get(0, 0).friction_coefficient, 0.4);
}

TEST(ParseScene, SelfGravityOptions) {
  const Scene tree = parse_scene(R"(
[time]
dt = 1
end_time = 100
[gravity]
type = "tree"
G = 1.0
theta = 0.7
order = 1
softening = 0.1
leaf_size = 8
group_size = 32
precision = "single"
[[materials]]
name = "m"
density = 1
[[contact_laws]]
materials = ["m", "m"]
friction = 0
[[generators]]
type = "cubic_grid"
cells_per_side = 3
radius_min = 0.3
radius_max = 0.5
distribution = "uniform_volume_fraction"
)",
                                 "tree.toml");
  const auto& g = tree.run.step.gravity;
  EXPECT_EQ(g.kind, GravitySettings::Kind::self);
  EXPECT_EQ(g.self_gravity.method, gravity::Method::tree);
  EXPECT_EQ(g.self_gravity.G, 1.0);
  EXPECT_EQ(g.self_gravity.theta, 0.7);
  EXPECT_EQ(g.self_gravity.order, 1);
  EXPECT_EQ(g.self_gravity.softening.kind, gravity::Softening::Kind::plummer);
  EXPECT_EQ(g.self_gravity.softening.length, 0.1);
  EXPECT_EQ(g.self_gravity.leaf_size, 8);
  EXPECT_EQ(g.self_gravity.group_size, 32);
  EXPECT_EQ(g.self_gravity.precision, gravity::KernelPrecision::single_precision);
  EXPECT_EQ(g.self_gravity.backend, gravity::Backend::cpu);
  ASSERT_EQ(tree.model.body_count(), 27u);
  // Default cubic-grid cell = 2 radius_max = 1 m, centred on the origin: every grain in [-1.5, 1.5]^3.
  for (std::size_t i = 0; i < 27; ++i) {
    EXPECT_LE(tree.state.position[i].cwiseAbs().maxCoeff() + tree.model.sphere_radius(i), 1.5 + 1e-12);
  }
}

TEST(ParseScene, GravityBackendIsRefusedAtItsLineWhereItCannotRun) {
  const auto scene_with = [](const std::string& backend) {
    return std::string(R"(
[time]
dt = 1
end_time = 100
[[materials]]
name = "m"
density = 1
[[contact_laws]]
materials = ["m", "m"]
friction = 0
[[bodies]]
shape = "sphere"
radius = 0.5
position = [0.0, 0.0, 0.0]
[[bodies]]
shape = "sphere"
radius = 0.5
position = [2.0, 0.0, 0.0]
[gravity]
type = "direct"
backend = ")") +
           backend + "\"\n";
  };
  const Scene cpu = parse_scene(scene_with("cpu"), "cpu.toml");
  EXPECT_EQ(cpu.run.step.gravity.self_gravity.backend, gravity::Backend::cpu);
  EXPECT_EQ(scene_to_toml(cpu).find("backend"), std::string::npos) << "the default backend is not written";

  gravity::GravityOptions direct_on_gpu;
  direct_on_gpu.method = gravity::Method::direct;
  direct_on_gpu.backend = gravity::Backend::cuda;
  const std::string reason = gravity::backend_unavailable_reason(direct_on_gpu);
  if (reason.empty()) {  // a GPU machine: the scene runs there and round-trips
    const Scene gpu = parse_scene(scene_with("cuda"), "gpu.toml");
    EXPECT_EQ(gpu.run.step.gravity.self_gravity.backend, gravity::Backend::cuda);
    EXPECT_NE(scene_to_toml(gpu).find("backend = \"cuda\""), std::string::npos);
    return;
  }
  try {
    parse_scene(scene_with("cuda"), "gpu.toml");
    FAIL() << "backend = \"cuda\" was accepted where it cannot run: " << reason;
  } catch (const SceneError& error) {
    EXPECT_EQ(error.key, "gravity.backend");
    EXPECT_EQ(error.line, 21);
    EXPECT_NE(std::string(error.what()).find(reason), std::string::npos) << error.what();
  }
}

// Cohesion keys of [[contact_laws]] (docs/scene-file.md): parsed into ContactLaw, written back
// (and only when set, so scenes without cohesion read as before), and a negative value refused at
// its line with the key's name.
TEST(ParseScene, CohesionKeysParseRoundTripAndAreRangeChecked) {
  const auto scene_with = [](const std::string& cohesion) {
    return std::string(R"([time]
dt = 1
end_time = 100
[[materials]]
name = "m"
density = 1
[[contact_laws]]
materials = ["m", "m"]
friction = 0.3
work_of_adhesion = 0.25
cohesion = )") +
           cohesion + R"(
[[bodies]]
shape = "sphere"
radius = 0.5
position = [0.0, 0.0, 0.0]
)";
  };
  const Scene scene = parse_scene(scene_with("2.5"), "cohesive.toml");
  EXPECT_EQ(scene.model.contact_laws.get(0, 0).cohesion, 2.5);
  EXPECT_EQ(scene.model.contact_laws.get(0, 0).work_of_adhesion, 0.25);
  const Scene again = parse_scene(scene_to_toml(scene), "again.toml");
  EXPECT_EQ(again.model.contact_laws.get(0, 0).cohesion, 2.5);
  EXPECT_EQ(again.model.contact_laws.get(0, 0).work_of_adhesion, 0.25);
  const Scene plain = parse_scene(two_grains_in_a_box, "two.toml");
  EXPECT_EQ(scene_to_toml(plain).find("cohesion"), std::string::npos);
  try {
    parse_scene(scene_with("-1"), "negative.toml");
    FAIL() << "cohesion = -1 was accepted";
  } catch (const SceneError& error) {
    EXPECT_EQ(error.key, "contact_laws[0].cohesion") << error.what();
    EXPECT_EQ(error.line, 11);
  }
}

// Rolling and twisting resistance act on sphere contacts only (docs/scene-file.md): a mixed scene
// whose spheres have a material of their own with rolling friction, and whose polyhedron pairs
// have none, is accepted and keeps the spheres' law; the same scene with rolling friction on the
// sphere-polyhedron pair is refused at that key's line (the corpus tests/scene/bad/ checks the
// message, rolling_friction_on_polyhedra.toml).
TEST(ParseScene, RollingFrictionOnSphereMaterialsBesidePolyhedraIsAccepted) {
  const auto scene_with = [](const std::string& mixed_pair_rolling) {
    return std::string(R"([time]
dt = 1e-4
end_time = 1
[[materials]]
name = "sand"
density = 2500
[[materials]]
name = "rock"
density = 2500
[[contact_laws]]
materials = ["sand", "sand"]
friction = 0.5
rolling_friction = 0.1
twisting_friction = 0.05
[[contact_laws]]
materials = ["sand", "rock"]
friction = 0.5
rolling_friction = )") +
           mixed_pair_rolling + R"(
[[contact_laws]]
materials = ["rock", "rock"]
friction = 0.5
[[bodies]]
shape = "sphere"
radius = 0.1
position = [0.0, 0.0, 0.0]
material = "sand"
[[bodies]]
shape = "polyhedron"
vertices = [[0.1, 0, 0], [-0.1, 0, 0], [0, 0.1, 0], [0, -0.1, 0], [0, 0, 0.1], [0, 0, -0.1]]
faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
position = [1.0, 0.0, 0.0]
material = "rock"
)";
  };
  const Scene scene = parse_scene(scene_with("0"), "mixed.toml");
  EXPECT_EQ(scene.model.contact_laws.get(0, 0).rolling_friction, 0.1);
  EXPECT_EQ(scene.model.contact_laws.get(0, 0).twisting_friction, 0.05);
  EXPECT_FALSE(scene.model.contact_laws.get(0, 1).resists_rotation());
  try {
    parse_scene(scene_with("0.1"), "mixed.toml");
    FAIL() << "rolling friction on a sphere-polyhedron pair was accepted";
  } catch (const SceneError& error) {
    EXPECT_EQ(error.key, "contact_laws[1].rolling_friction") << error.what();
    EXPECT_EQ(error.line, 18);
  }
}

TEST(TimeControl, AutoStepAndRestCriterionFollowTheScene) {
  const std::string grid = "type = \"cubic_grid\"\ncells_per_side = 4\nradius_min = 3.75\nradius_max = 5.0\n";
  const Scene automatic =
      parse_scene(cloud_scene(grid, "dt = \"auto\"\nend_time = 9000.0\nuntil = \"rest\"\n"), "auto.toml");
  const SceneScales scales = scene_scales(automatic.model, automatic.state, automatic.run.step.gravity);
  EXPECT_TRUE(automatic.run.automatic_time_step);
  EXPECT_EQ(automatic.run.step.integrator.time_step,
            automatic_time_step(automatic.model, automatic.state, automatic.run.step.gravity).time_step);
  EXPECT_TRUE(automatic.run.until_rest);
  EXPECT_DOUBLE_EQ(automatic.run.rest.speed, automatic_rest_criterion(scales).speed);
  EXPECT_DOUBLE_EQ(automatic.run.rest.speed, auto_rest_speed_fraction * scales.rest_reference_velocity);
  EXPECT_EQ(automatic.run.rest.quantile, 0.99);
  EXPECT_DOUBLE_EQ(automatic.run.rest.coordination_change, 0.05 * std::sqrt(1000.0 / 64.0));  // 4^3 grains
  EXPECT_EQ(automatic.run.rest.contact_change, 0.2);
  EXPECT_DOUBLE_EQ(automatic.run.rest.duration, automatic_rest_criterion(scales).duration);
  const Scene given =
      parse_scene(cloud_scene(grid,
                              "dt = 0.5\nend_time = 9000.0\nuntil = \"rest\"\nrest_speed = 2.5\nrest_quantile = 1\n"
                              "rest_coordination_change = 0.125\nrest_contact_change = 0.25\nrest_duration = 0\n"),
                  "given.toml");
  EXPECT_FALSE(given.run.automatic_time_step);
  EXPECT_EQ(given.run.step.integrator.time_step, 0.5);
  EXPECT_EQ(given.run.rest.speed, 2.5);
  EXPECT_EQ(given.run.rest.quantile, 1.0);
  EXPECT_EQ(given.run.rest.coordination_change, 0.125);
  EXPECT_EQ(given.run.rest.contact_change, 0.25);
  EXPECT_EQ(given.run.rest.duration, 0.0);
  // Written back and read again, the given thresholds stay.
  const Scene again = parse_scene(scene_to_toml(given), "again.toml");
  EXPECT_EQ(again.run.rest.speed, 2.5);
  EXPECT_EQ(again.run.rest.quantile, 1.0);
  EXPECT_EQ(again.run.rest.coordination_change, 0.125);
  EXPECT_EQ(again.run.rest.contact_change, 0.25);
  // The key of the old energy criterion says what replaced it.
  try {
    parse_scene(cloud_scene(grid, "dt = 0.5\nend_time = 9000.0\nuntil = \"rest\"\nrest_kinetic_energy = 2.5\n"),
                "old.toml");
    ADD_FAILURE() << "rest_kinetic_energy was accepted";
  } catch (const SceneError& error) {
    EXPECT_NE(std::string(error.what()).find("replaced by rest_speed"), std::string::npos) << error.what();
  }
  const Scene fixed = parse_scene(cloud_scene(grid, "dt = 0.5\nend_time = 100.0\n"), "fixed.toml");
  EXPECT_FALSE(fixed.run.until_rest);
  // Written back, "auto" stays "auto" (and so gives the same step again).
  const std::string text = scene_to_toml(automatic);
  EXPECT_NE(text.find("dt = \"auto\""), std::string::npos);
  EXPECT_NE(text.find("until = \"rest\""), std::string::npos);
  EXPECT_EQ(parse_scene(text, "again.toml").run.step.integrator.time_step, automatic.run.step.integrator.time_step);
}

TEST(TimeControl, AutoStepWithoutAnyTimeScaleIsASceneError) {
  const std::string text =
      "[time]\ndt = \"auto\"\nend_time = 1.0\n[[materials]]\nname = \"rock\"\ndensity = 1.0\n"
      "[default_contact_law]\nfriction = 0.0\n[[bodies]]\nshape = \"sphere\"\nradius = 1.0\n"
      "position = [0, 0, 0]\n";
  try {
    parse_scene(text, "still.toml");
    FAIL() << "expected a SceneError";
  } catch (const SceneError& error) {
    EXPECT_EQ(error.key, "time.dt");
    EXPECT_NE(error.message.find("nothing sets a time scale"), std::string::npos) << error.message;
  }
}

TEST(SceneError, WhatIsFileLineKeyMessage) {
  EXPECT_STREQ(SceneError("a.toml", 12, "bodies[3].radius", "expected a number > 0, got -1").what(),
               "a.toml:12: bodies[3].radius: expected a number > 0, got -1");
  EXPECT_STREQ(SceneError("a.toml", 0, "time", "missing").what(), "a.toml: time: missing");
  EXPECT_STREQ(SceneError("a.toml", 3, "", "syntax").what(), "a.toml:3: syntax");
}

TEST(LoadSceneFile, MissingFileIsASceneError) {
  try {
    load_scene_file("/nonexistent/dir/none.toml");
    FAIL() << "no SceneError";
  } catch (const SceneError& error) {
    EXPECT_EQ(error.file, "/nonexistent/dir/none.toml");
    EXPECT_NE(std::string(error.what()).find("cannot open"), std::string::npos);
  }
}

// --- the corpus of bad scene files ---

/// The files of tests/scene/bad/, sorted.
std::vector<std::string> bad_scene_files() {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(RUBBLE_SCENE_BAD_DIR)) {
    if (entry.path().extension() == ".toml") names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

TEST(BadScenes, CorpusHasAtLeast25Files) { EXPECT_GE(bad_scene_files().size(), 25u); }

/// The value of a "# NAME: value" header line, or "" if absent.
std::string header(const std::string& text, const std::string& name) {
  std::istringstream lines(text);
  std::string line;
  const std::string prefix = "# " + name + ": ";
  while (std::getline(lines, line) && line.rfind("#", 0) == 0) {
    if (line.rfind(prefix, 0) == 0) return line.substr(prefix.size());
  }
  return "";
}

class BadScene : public ::testing::TestWithParam<std::string> {};

TEST_P(BadScene, IsRejectedWithTheExpectedMessage) {
  const std::filesystem::path path = std::filesystem::path(RUBBLE_SCENE_BAD_DIR) / GetParam();
  const std::string text = read_text(path);
  const std::string expected = header(text, "expect");
  ASSERT_FALSE(expected.empty()) << path << " lacks its first-line '# expect: <message part>'";
  try {
    load_scene_file(path);
    FAIL() << path << " was accepted";
  } catch (const SceneError& error) {
    const std::string what = error.what();
    EXPECT_NE(what.find(expected), std::string::npos) << "got: " << what << "\nexpected to contain: " << expected;
    EXPECT_NE(what.find(GetParam()), std::string::npos) << what;
    EXPECT_EQ(error.file, path.string());
    const std::string line = header(text, "line");
    if (!line.empty()) {
      EXPECT_EQ(error.line, std::stoi(line)) << what;
      EXPECT_NE(what.find(GetParam() + ":" + line + ":"), std::string::npos) << what;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Corpus, BadScene, ::testing::ValuesIn(bad_scene_files()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = std::filesystem::path(info.param).stem().string();
                           for (char& c : name) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return name;
                         });

// Huge but finite quaternions and wall normals are directions: [1e200, 0, 1e200, 0] is 90 degrees
// about y (its plain norm overflowed and made the zero quaternion, a grain that never turned), a
// normal of [0, 0, 1e200] is +z.
TEST(ParseScene, HugeQuaternionsAndNormalsAreNormalisedWithoutOverflow) {
  const Scene scene = parse_scene(R"(
[time]
dt = 1e-4
end_time = 0.01
[[materials]]
name = "rock"
density = 2500.0
[[contact_laws]]
materials = ["rock", "rock"]
friction = 0.3
[[walls]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1e200]
[[bodies]]
shape = "sphere"
radius = 0.01
position = [0.0, 0.0, 0.5]
orientation = [1e200, 0.0, 1e200, 0.0]
)",
                                  "huge.toml");
  const Quat q = scene.state.orientation[0];
  EXPECT_NEAR(q.w(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(q.y(), std::sqrt(0.5), 1e-15);
  EXPECT_EQ(q.x(), 0.0);
  EXPECT_EQ(q.z(), 0.0);
  ASSERT_EQ(scene.model.planes.size(), 1u);
  const Vec3 normal = scene.state.orientation[1] * scene.model.planes[0].normal;  // body 1: the wall
  EXPECT_NEAR(normal.z(), 1.0, 1e-15);
}

}  // namespace
}  // namespace rubble
