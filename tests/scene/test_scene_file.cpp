// Tests of simulation/scene_file.cpp: good scenes give the model, state and options they describe
// (masses against 4/3 pi r^3 rho), the default scene parses and matches examples/box-deposit.toml,
// scene_to_toml round-trips bit for bit, and every file of the corpus bad/*.toml is rejected with
// a SceneError carrying the expected message, the file name and the line.
#include "simulation/scene_file.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

namespace rubble {
namespace {

constexpr const char* two_grains_in_a_box = R"(
name = "two"
seed = 9
[time]
dt = 2e-4
theta = 0.75
end_time = 0.5
[solver]
tolerance = 1e-6
max_iterations = 200
relaxation = 0.9
warm_start = false
penetration_correction = 0.5
max_correction_velocity = 0.25
[detection]
alert_distance = 0.001
[gravity]
type = "uniform"
acceleration = [0, 0, -9.81]
[output]
directory = "out"
snapshot_every_steps = 50
progress_interval = 0
vtk = true
[[materials]]
name = "rock"
density = 3000
[[materials]]
name = "wall"
density = 1
[[contact_laws]]
materials = ["rock", "rock"]
friction = 0.5
restitution = 0.1
[[contact_laws]]
materials = ["wall", "rock"]
friction = 0.2
[[walls]]
type = "plane"
point = [0, 0, -1]
normal = [0, 0, 2]
material = "wall"
[[walls]]
type = "box"
center = [5, 0, 0]
half_extents = [1, 2, 3]
orientation = [0, 0, 0, 2]
material = "wall"
[[bodies]]
shape = "sphere"
radius = 0.5
position = [0, 0, 0]
velocity = [1, 2, 3]
angular_velocity = [0.1, 0.2, 0.3]
material = "rock"
[[bodies]]
shape = "sphere"
radius = 0.25
position = [2, 0, 0]
material = "rock"
)";

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
  EXPECT_EQ(scene.run.step.solver.penetration_correction, 0.5);
  EXPECT_EQ(scene.run.step.solver.max_correction_velocity, 0.25);
  EXPECT_EQ(scene.run.step.detection.alert_distance, 0.001);
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
  ASSERT_EQ(tree.model.body_count(), 27u);
  // Default cubic-grid cell = 2 radius_max = 1 m, centred on the origin: every grain in [-1.5, 1.5]^3.
  for (std::size_t i = 0; i < 27; ++i) {
    EXPECT_LE(tree.state.position[i].cwiseAbs().maxCoeff() + tree.model.sphere_radius(i), 1.5 + 1e-12);
  }
}

TEST(DefaultScene, ParsesToAThousandSpheresInAnOpenBox) {
  const Scene scene = default_scene();
  EXPECT_EQ(scene.name, "box-deposit");
  ASSERT_EQ(scene.model.body_count(), 1005u);
  EXPECT_EQ(scene.model.spheres.size(), 1000u);
  EXPECT_EQ(scene.model.planes.size(), 5u);
  EXPECT_EQ(scene.run.step.gravity.kind, GravitySettings::Kind::uniform);
  EXPECT_EQ(scene.run.step.integrator.time_step, 1e-4);
  for (std::size_t i = 0; i < 1000; ++i) {
    const Vec3& x = scene.state.position[i];
    const double r = scene.model.sphere_radius(i);
    EXPECT_GE(r, 0.04);
    EXPECT_LE(r, 0.06);
    EXPECT_LE(std::max(std::abs(x.x()), std::abs(x.y())) + r, 0.6 + 1e-12);
    EXPECT_GE(x.z() - r, -1e-12);
  }
}

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(DefaultScene, IsTheExampleFileAndLoadsFromIt) {
  const std::filesystem::path example = std::filesystem::path(RUBBLE_EXAMPLES_DIR) / "box-deposit.toml";
  EXPECT_EQ(read_text(example), default_scene_toml()) << "regenerate with: rubble run --print-default-scene > "
                                                         "examples/box-deposit.toml";
  const Scene from_file = load_scene_file(example);
  const Scene built_in = default_scene();
  ASSERT_EQ(from_file.state.body_count(), built_in.state.body_count());
  for (std::size_t i = 0; i < built_in.state.body_count(); ++i) {
    EXPECT_EQ(from_file.state.position[i], built_in.state.position[i]);
  }
}

TEST(Examples, EveryExampleFileParses) {
  std::size_t count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(RUBBLE_EXAMPLES_DIR)) {
    if (entry.path().extension() != ".toml") continue;
    ++count;
    EXPECT_NO_THROW({
      const Scene scene = load_scene_file(entry.path());
      EXPECT_GT(scene.model.body_count(), 0u);
    }) << entry.path();
  }
  EXPECT_GE(count, 2u);
}

TEST(DefaultScene, SameSeedSameGrainsOtherSeedOtherGrains) {
  std::string text = default_scene_toml();
  const Scene a = parse_scene(text, "a.toml");
  const Scene b = parse_scene(text, "b.toml");
  text.replace(text.find("seed = 1"), 8, "seed = 2");
  const Scene c = parse_scene(text, "c.toml");
  std::size_t differing = 0;
  for (std::size_t i = 0; i < 1000; ++i) {
    EXPECT_EQ(a.state.position[i], b.state.position[i]);
    differing += a.state.position[i] != c.state.position[i] ? 1 : 0;
  }
  EXPECT_EQ(differing, 1000u);
}

/// Same model and state, bit for bit.
void expect_same_scene(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.run.seed, b.run.seed);
  EXPECT_EQ(a.run.end_time, b.run.end_time);
  EXPECT_EQ(a.run.step.integrator.time_step, b.run.step.integrator.time_step);
  EXPECT_EQ(a.run.step.integrator.theta, b.run.step.integrator.theta);
  EXPECT_EQ(a.run.step.solver.tolerance, b.run.step.solver.tolerance);
  EXPECT_EQ(a.run.step.solver.warm_start, b.run.step.solver.warm_start);
  EXPECT_EQ(a.run.step.gravity.kind, b.run.step.gravity.kind);
  EXPECT_EQ(a.run.step.gravity.acceleration, b.run.step.gravity.acceleration);
  EXPECT_EQ(a.run.output.directory, b.run.output.directory);
  EXPECT_EQ(a.run.output.snapshot_every_steps, b.run.output.snapshot_every_steps);
  EXPECT_EQ(a.run.output.snapshot_interval, b.run.output.snapshot_interval);
  EXPECT_EQ(a.run.output.write_vtk, b.run.output.write_vtk);
  ASSERT_EQ(a.model.body_count(), b.model.body_count());
  EXPECT_EQ(a.model.shape_kind, b.model.shape_kind);
  EXPECT_EQ(a.model.material, b.model.material);
  EXPECT_EQ(a.model.mass, b.model.mass);
  EXPECT_EQ(a.model.contact_laws.laws.size(), b.model.contact_laws.laws.size());
  for (std::size_t k = 0; k < a.model.contact_laws.laws.size(); ++k) {
    EXPECT_EQ(a.model.contact_laws.laws[k].friction_coefficient, b.model.contact_laws.laws[k].friction_coefficient);
    EXPECT_EQ(a.model.contact_laws.laws[k].normal_restitution, b.model.contact_laws.laws[k].normal_restitution);
  }
  for (std::size_t i = 0; i < a.model.body_count(); ++i) {
    EXPECT_EQ(a.model.bounding_radius[i], b.model.bounding_radius[i]) << i;
    EXPECT_EQ(a.state.position[i], b.state.position[i]) << i;
    EXPECT_EQ(a.state.orientation[i].coeffs(), b.state.orientation[i].coeffs()) << i;
    EXPECT_EQ(a.state.velocity[i], b.state.velocity[i]) << i;
    EXPECT_EQ(a.state.angular_velocity[i], b.state.angular_velocity[i]) << i;
  }
  for (std::size_t k = 0; k < a.model.planes.size(); ++k) EXPECT_EQ(a.model.planes[k].normal, b.model.planes[k].normal);
  for (std::size_t k = 0; k < a.model.boxes.size(); ++k) {
    EXPECT_EQ(a.model.boxes[k].half_extents, b.model.boxes[k].half_extents);
  }
}

TEST(SceneToToml, RoundTripsBitForBit) {
  for (const Scene& original : {parse_scene(two_grains_in_a_box, "two.toml"), default_scene()}) {
    const std::string text = scene_to_toml(original);
    const Scene again = parse_scene(text, "written.toml");
    expect_same_scene(original, again);
    EXPECT_EQ(scene_to_toml(again), text);  // and writing is stable
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

}  // namespace
}  // namespace rubble
