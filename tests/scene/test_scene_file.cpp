// Tests of simulation/scene_file.cpp: good scenes give the model, state and options they describe
// (masses against 4/3 pi r^3 rho), the default scene parses and matches examples/accretion-1000.toml,
// scene_to_toml round-trips bit for bit, and every file of the corpus bad/*.toml is rejected with
// a SceneError carrying the expected message, the file name and the line.
#include "simulation/run_control.hpp"
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
polish_after = 15
polish_iterations = 7
polish_max_contacts = 700
[detection]
alert_distance = 0.001
pair_list_margin = 0.002
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

TEST(DefaultScene, IsTheThousandSphereAccretionToRest) {
  const Scene scene = default_scene();
  EXPECT_EQ(scene.name, "accretion-1000");
  ASSERT_EQ(scene.model.body_count(), 1000u);
  EXPECT_EQ(scene.model.spheres.size(), 1000u);
  EXPECT_EQ(scene.run.step.gravity.kind, GravitySettings::Kind::self);
  EXPECT_EQ(scene.run.step.gravity.self_gravity.method, gravity::Method::tree);
  EXPECT_TRUE(scene.run.automatic_time_step);
  EXPECT_EQ(scene.run.step.integrator.time_step,
            automatic_time_step(scene.model, scene.state, scene.run.step.gravity).time_step);
  EXPECT_TRUE(scene.run.until_rest);
  EXPECT_GT(scene.run.rest.speed, 0.0);
  EXPECT_GT(scene.run.rest.duration, 0.0);
  for (std::size_t i = 0; i < 1000; ++i) {
    const double r = scene.model.sphere_radius(i);
    EXPECT_GE(r, 3.75);
    EXPECT_LE(r, 5.0);
    EXPECT_LE(scene.state.position[i].cwiseAbs().maxCoeff() + r, 50.0 + 1e-9);
    EXPECT_EQ(scene.state.velocity[i], Vec3::Zero());
  }
}

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(DefaultScene, IsTheExampleFileAndLoadsFromIt) {
  const std::filesystem::path example = std::filesystem::path(RUBBLE_EXAMPLES_DIR) / "accretion-1000.toml";
  EXPECT_EQ(read_text(example), default_scene_toml()) << "regenerate with: rubble run --print-default-scene > "
                                                         "examples/accretion-1000.toml";
  const Scene from_file = load_scene_file(example);
  const Scene built_in = default_scene();
  ASSERT_EQ(from_file.state.body_count(), built_in.state.body_count());
  for (std::size_t i = 0; i < built_in.state.body_count(); ++i) {
    EXPECT_EQ(from_file.state.position[i], built_in.state.position[i]);
  }
}

// The polyhedra variant (`rubble run --default-scene polyhedra`): the same set-up, 1000 random
// polyhedra (every grain a polyhedron, none a sphere), and the example file holds its text.
TEST(DefaultScene, PolyhedraVariantIsTheExampleFileAndHoldsOnlyPolyhedra) {
  const std::filesystem::path example = std::filesystem::path(RUBBLE_EXAMPLES_DIR) / "accretion-1000-polyhedra.toml";
  EXPECT_EQ(read_text(example), default_scene_toml(DefaultScene::polyhedra))
      << "regenerate with: rubble run --default-scene polyhedra --print-default-scene > "
         "examples/accretion-1000-polyhedra.toml";
  const Scene scene = default_scene(DefaultScene::polyhedra);
  const Scene spheres = default_scene();
  std::size_t polyhedra = 0, grains = 0;
  for (std::size_t b = 0; b < scene.model.body_count(); ++b) {
    if (!scene.model.is_grain(b)) continue;
    ++grains;
    if (scene.model.shape_kind[b] == ShapeKind::polyhedron) ++polyhedra;
  }
  EXPECT_EQ(grains, 1000u);
  EXPECT_EQ(polyhedra, grains);
  EXPECT_EQ(scene.run.step.gravity.kind, spheres.run.step.gravity.kind);
  EXPECT_EQ(scene.run.end_time, spheres.run.end_time);
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

// examples/accretion/: the study's sets (the LMGC90 accretion paper), each file what its name says: spheres-N,
// polyhedra-N (N grains on the cubic grid of mesh 10 m), spheres-3375-muM (friction M), all with
// density 5164, diameters in [7.5, 10] m, mu = 0 unless named, dt = "auto", until = "rest".
TEST(Examples, AccretionStudyFilesAreTheirCases) {
  std::size_t files = 0;
  for (const auto& entry :
       std::filesystem::directory_iterator(std::filesystem::path(RUBBLE_EXAMPLES_DIR) / "accretion")) {
    if (entry.path().extension() != ".toml") continue;
    ++files;
    const std::string stem = entry.path().stem().string();
    SCOPED_TRACE(stem);
    const Scene scene = load_scene_file(entry.path());
    const bool polyhedra = stem.rfind("polyhedra-", 0) == 0;
    const std::size_t dash = stem.find('-');
    const std::size_t count = std::stoul(stem.substr(dash + 1));
    const std::size_t mu_at = stem.find("-mu");
    const double mu = mu_at == std::string::npos ? 0.0 : std::stod(stem.substr(mu_at + 3));
    EXPECT_EQ(scene.name, stem);
    ASSERT_EQ(scene.model.body_count(), count);
    EXPECT_EQ(polyhedra ? scene.model.polyhedra.size() : scene.model.spheres.size(), count);
    EXPECT_EQ(scene.model.materials.at(0).density, 5164.0);
    EXPECT_EQ(scene.model.contact_laws.get(0, 0).friction_coefficient, mu);
    EXPECT_EQ(scene.model.contact_laws.get(0, 0).normal_restitution, 0.0);
    EXPECT_TRUE(scene.run.automatic_time_step);
    EXPECT_TRUE(scene.run.until_rest);
    EXPECT_EQ(scene.run.step.gravity.kind, GravitySettings::Kind::self);
    const double k = std::round(std::cbrt(static_cast<double>(count)));
    for (std::size_t b = 0; b < count; ++b) {
      EXPECT_LE(scene.state.position[b].cwiseAbs().maxCoeff(), 5.0 * k);
      if (!polyhedra) {
        EXPECT_GE(scene.model.sphere_radius(b), 3.75);
        EXPECT_LE(scene.model.sphere_radius(b), 5.0);
      }
    }
  }
  EXPECT_EQ(files, 18u);  // 7 sphere sets, 5 polyhedra sets, 6 friction values
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

// Driven walls and bodies (docs/scene-file.md, "Driven bodies"): a plane moving by a table, a box
// turning at a constant rate, a held grain and an impactor. They parse into prescribed motions with
// infinite mass, start at their prescribed velocities, and are written back bit for bit.
TEST(SceneToToml, DrivenWallsAndBodiesRoundTrip) {
  const Scene original = parse_scene(std::string(two_grains_in_a_box) + R"(
[[walls]]
type = "plane"
point = [0.0, 0.0, 5.0]
normal = [0.0, 0.0, -1.0]
motion = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.5, 0.0, 0.0, 0.25]]
material = "wall"
[[walls]]
type = "box"
center = [0.0, 0.0, 7.0]
half_extents = [0.1, 0.1, 0.1]
angular_velocity = [0.0, 0.0, 2.0]
material = "wall"
[[bodies]]
shape = "sphere"
radius = 0.05
position = [0.0, 0.0, 3.0]
driven = true
material = "rock"
[[bodies]]
shape = "sphere"
radius = 0.05
position = [0.0, 0.0, 4.0]
driven = true
velocity = [0.0, 0.0, -3.0]
material = "rock"
)",
                                     "driven.toml");
  const Model& model = original.model;
  ASSERT_EQ(model.driven_bodies.size(), 4u);
  for (const std::size_t b : model.driven_bodies) {
    EXPECT_TRUE(model.is_fixed(b));
    EXPECT_EQ(model.mass[b], 0.0);
  }
  const std::size_t impactor = model.driven_bodies[1];
  EXPECT_TRUE(model.is_grain(impactor));
  EXPECT_EQ(original.state.velocity[impactor], Vec3(0, 0, -3.0));
  EXPECT_EQ(model.driven_velocity(model.driven_bodies[2], 0.5).linear, Vec3(0, 0, -0.25));
  EXPECT_EQ(original.state.angular_velocity[model.driven_bodies[3]], Vec3(0, 0, 2.0));
  const std::string text = scene_to_toml(original);
  const Scene again = parse_scene(text, "written.toml");
  expect_same_scene(original, again);
  EXPECT_EQ(again.model.driven_bodies, model.driven_bodies);
  for (std::size_t k = 0; k < model.prescribed_motions.size(); ++k) {
    EXPECT_EQ(again.model.prescribed_motions[k].time, model.prescribed_motions[k].time);
    EXPECT_EQ(again.model.prescribed_motions[k].velocity, model.prescribed_motions[k].velocity);
    EXPECT_EQ(again.model.prescribed_motions[k].angular_velocity, model.prescribed_motions[k].angular_velocity);
  }
  EXPECT_EQ(scene_to_toml(again), text);
}

/// A minimal self-gravitating scene around one generator table (its keys in `generator`).
std::string cloud_scene(const std::string& generator, const std::string& time = "dt = \"auto\"\nend_time = 9000.0\n",
                        int seed = 1) {
  return "seed = " + std::to_string(seed) + "\n[time]\n" + time +
         "[gravity]\ntype = \"tree\"\n[[materials]]\nname = \"rock\"\ndensity = 5164.0\n"
         "[default_contact_law]\nfriction = 0.0\n[[generators]]\n" +
         generator;
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

/// Index (i, j, k) of the cubic-grid cell of grain `ordinal` (x fastest) and that cell's lower corner.
Vec3 cell_corner(std::size_t ordinal, std::size_t k, double cell) {
  const Vec3 ijk(static_cast<double>(ordinal % k), static_cast<double>((ordinal / k) % k),
                 static_cast<double>(ordinal / (k * k)));
  return Vec3::Constant(-0.5 * static_cast<double>(k) * cell) + cell * ijk;
}

// The paper's polyhedra: every vertex of every grain inside its own cell of the grid (so no two
// grains overlap), circumscribed diameters in [d_min, d_max], n_v in [10, 70] before merging.
TEST(PolyhedronGenerator, CubicGridPolyhedraStayInsideTheirCells) {
  const std::string grid =
      "type = \"cubic_grid\"\ncells_per_side = 4\nshape = \"polyhedron\"\nradius_min = 3.75\n"
      "radius_max = 5.0\ndistribution = \"uniform_volume_fraction\"\n";
  const Scene scene = parse_scene(cloud_scene(grid), "poly.toml");
  ASSERT_EQ(scene.model.body_count(), 64u);
  ASSERT_EQ(scene.model.polyhedra.size(), 64u);
  for (std::size_t b = 0; b < 64; ++b) {
    ASSERT_EQ(scene.model.shape_kind[b], ShapeKind::polyhedron);
    const ConvexPolyhedron& shape = scene.model.polyhedra[static_cast<std::size_t>(scene.model.shape_index[b])];
    const Vec3 corner = cell_corner(b, 4, 10.0);
    std::vector<Vec3> world;
    for (const Vec3& v : shape.vertices) {
      const Vec3 x = scene.state.position[b] + scene.state.orientation[b] * v;
      world.push_back(x);
      for (int axis = 0; axis < 3; ++axis) {
        EXPECT_GE(x[axis], corner[axis] - 1e-9) << b;
        EXPECT_LE(x[axis], corner[axis] + 10.0 + 1e-9) << b;
      }
    }
    double diameter = 0.0;  // largest vertex distance <= circumscribed diameter
    for (const Vec3& p : world) {
      for (const Vec3& q : world) diameter = std::max(diameter, (p - q).norm());
    }
    EXPECT_LE(diameter, 10.0 + 1e-9);
    EXPECT_GE(diameter, 0.5 * 7.5);  // elongation and platyness >= 0.5 keep it at least half as wide
    EXPECT_LE(shape.vertices.size(), 70u);
  }
}

TEST(PolyhedronGenerator, MixFractionAndSameSeedSameFile) {
  const std::string mix =
      "type = \"cubic_grid\"\ncells_per_side = 8\nshape = \"mix\"\npolyhedron_fraction = 0.25\n"
      "radius_min = 3.75\nradius_max = 5.0\n";
  const Scene scene = parse_scene(cloud_scene(mix), "mix.toml");
  // 512 grains, each a polyhedron with probability 1/4: 128 +- 10 (binomial sd); tolerance 4 sd.
  EXPECT_NEAR(static_cast<double>(scene.model.polyhedra.size()), 128.0, 40.0);
  EXPECT_EQ(scene.model.polyhedra.size() + scene.model.spheres.size(), 512u);
  // Written out twice from the same seed: the same file; another seed: another file.
  const std::string small =
      "type = \"cubic_grid\"\ncells_per_side = 3\nshape = \"mix\"\npolyhedron_fraction = 0.5\n"
      "radius_min = 3.75\nradius_max = 5.0\n";
  const std::string a = scene_to_toml(parse_scene(cloud_scene(small), "a.toml"));
  const std::string b = scene_to_toml(parse_scene(cloud_scene(small), "a.toml"));
  const std::string c =
      scene_to_toml(parse_scene(cloud_scene(small, "dt = \"auto\"\nend_time = 9000.0\n", 2), "a.toml"));
  EXPECT_TRUE(a == b) << "the same seed wrote two different files";
  EXPECT_TRUE(a != c) << "another seed wrote the same file";
  // The written polyhedra read back: same shapes (vertices bit for bit), positions and masses
  // to round-off (the mass properties are recomputed from the merged faces).
  const Scene original = parse_scene(cloud_scene(small), "a.toml");
  const Scene again = parse_scene(a, "written.toml");
  ASSERT_EQ(again.model.body_count(), original.model.body_count());
  for (std::size_t i = 0; i < original.model.body_count(); ++i) {
    EXPECT_EQ(again.model.shape_kind[i], original.model.shape_kind[i]);
    EXPECT_NEAR(again.model.mass[i], original.model.mass[i], 1e-2 * original.model.mass[i]) << i;
    EXPECT_LT((again.state.position[i] - original.state.position[i]).norm(), 1e-2) << i;
  }
}

TEST(PolyhedronBodies, RandomAndListedVertices) {
  const std::string text = R"(
[time]
dt = 1e-3
end_time = 1.0
[[materials]]
name = "rock"
density = 2000.0
[default_contact_law]
friction = 0.5
[[bodies]]
shape = "polyhedron"
diameter = 2.0
position = [0, 0, 0]
[[bodies]]
shape = "polyhedron"
position = [5, 0, 0]
vertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]
faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5], [0, 4, 7, 3]]
)";
  const Scene scene = parse_scene(text, "bodies.toml");
  ASSERT_EQ(scene.model.polyhedra.size(), 2u);
  // The unit cube listed with its corner at `position`: centroid at position + (0.5, 0.5, 0.5),
  // mass = density x 1 m^3, inertia m (1 + 1) / 12 about each axis.
  EXPECT_NEAR(scene.model.mass[1], 2000.0, 1e-9);
  EXPECT_LT((scene.state.position[1] - Vec3(5.5, 0.5, 0.5)).norm(), 1e-12);
  EXPECT_NEAR(scene.model.principal_inertia[1].x(), 2000.0 / 6.0, 1e-9);
  EXPECT_LE(scene.model.bounding_radius[0], 2.0);
  const std::string missing =
      "[time]\ndt = 1e-3\nend_time = 1.0\n[[materials]]\nname = \"rock\"\ndensity = 1.0\n"
      "[default_contact_law]\nfriction = 0.0\n[[bodies]]\nshape = \"polyhedron\"\n"
      "position = [0, 0, 0]\n";
  EXPECT_THROW(parse_scene(missing, "missing.toml"), SceneError);
}

TEST(Generators, SphereCloudMonodisperseAndBins) {
  const Scene cloud = parse_scene(
      cloud_scene("type = \"sphere_cloud\"\ncount = 300\nvolume_fraction = 0.1\ndistribution = \"monodisperse\"\n"
                  "radius = 1.0\ncenter = [1, 2, 3]\n"),
      "cloud.toml");
  ASSERT_EQ(cloud.model.body_count(), 300u);
  const double ball = std::cbrt(300.0 / 0.1);  // N r^3 / nu with r = 1
  for (std::size_t i = 0; i < 300; ++i) {
    EXPECT_EQ(cloud.model.sphere_radius(i), 1.0);
    EXPECT_LE((cloud.state.position[i] - Vec3(1, 2, 3)).norm() + 1.0, ball * (1 + 1e-12));
  }
  const Scene binned = parse_scene(
      cloud_scene("type = \"cubic_grid\"\ncells_per_side = 5\ndistribution = \"bins\"\nbins = [[8.0, 1], [10.0, 0]]\n"),
      "bins.toml");
  for (std::size_t i = 0; i < 125; ++i) EXPECT_EQ(binned.model.sphere_radius(i), 4.0);
  EXPECT_THROW(parse_scene(cloud_scene("type = \"sphere_cloud\"\ncount = 10\nradius = 1.0\n"
                                       "distribution = \"monodisperse\"\n"),
                           "neither.toml"),
               SceneError);
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
