// Tests of the default scenes (simulation/scene_defaults.cpp) and the example files: the default
// scene is the 1000-sphere accretion to rest and examples/accretion-1000*.toml hold its text, every
// example parses, the study's files are their cases, the seed decides the grains.
#include "simulation/run_control.hpp"
#include "simulation/scene_file.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

#include "scene/scene_test_scenes.hpp"

namespace rubble {
namespace {

using scene_test::cloud_scene;
using scene_test::read_text;
using scene_test::two_grains_in_a_box;

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

// examples/angle-of-repose/: the four heaps of issue 20, each what its name says: heap-murM has rolling
// resistance M, and all share mu = 0.5, e_n = 0, no twisting resistance, a floor of 1 781 fixed spheres
// over a disc of radius 0.25 m, and an inflow of 2 000 grains at 1 000 grains/s.
TEST(Examples, AngleOfReposeFilesAreTheirCases) {
  std::size_t files = 0;
  for (const auto& entry :
       std::filesystem::directory_iterator(std::filesystem::path(RUBBLE_EXAMPLES_DIR) / "angle-of-repose")) {
    if (entry.path().extension() != ".toml") continue;
    ++files;
    const std::string stem = entry.path().stem().string();
    SCOPED_TRACE(stem);
    const Scene scene = load_scene_file(entry.path());
    EXPECT_EQ(scene.name, stem);
    const ContactLaw& law = scene.model.contact_laws.get(0, 0);
    EXPECT_EQ(law.rolling_friction, std::stod(stem.substr(stem.find("mur") + 3)));
    EXPECT_EQ(law.friction_coefficient, 0.5);
    EXPECT_EQ(law.normal_restitution, 0.0);
    EXPECT_EQ(law.twisting_friction, 0.0);
    ASSERT_EQ(scene.inflow.inflows.size(), 1u);
    EXPECT_EQ(scene.inflow.inflows[0].count, 2000u);
    EXPECT_EQ(scene.inflow.inflows[0].rate, 1000.0);
    EXPECT_EQ(scene.inflow.first_body, 1782u);  // the floor's spheres and the plane under them
    std::size_t floor = 0;
    for (std::size_t b = 0; b < scene.inflow.first_body; ++b) {
      if (!scene.model.is_driven(b)) continue;
      ++floor;
      EXPECT_LE(std::hypot(scene.state.position[b].x(), scene.state.position[b].y()), 0.25);
    }
    EXPECT_EQ(floor, 1781u);
  }
  EXPECT_EQ(files, 4u);  // mu_r = 0, 0.05, 0.1, 0.2
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

// examples/spin-up/: each stage scene spin-muM-cF must hold the bodies of accretion-muM (a branch
// with --from refuses other bodies, and the stages' radii and the settled state must belong to the
// same grains), with friction M, pull-off force F N, no restitution, and one rigid spin increment
// through the centre of mass, along z in the file (run.sh turns it onto the aggregate's axis of
// largest moment of inertia; examples/spin-up/README.md).
TEST(Examples, SpinUpStagesHoldTheirAccretionsBodiesAndTheirContactLaw) {
  const std::filesystem::path folder = std::filesystem::path(RUBBLE_EXAMPLES_DIR) / "spin-up";
  std::size_t stages = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const std::string stem = entry.path().stem().string();
    if (entry.path().extension() != ".toml" || stem.rfind("spin-mu", 0) != 0) continue;
    ++stages;
    SCOPED_TRACE(stem);
    const std::size_t c_at = stem.find("-c");
    const std::string mu = stem.substr(7, c_at - 7);
    const Scene stage = load_scene_file(entry.path());
    const Scene accretion = load_scene_file(folder / ("accretion-mu" + mu + ".toml"));
    ASSERT_EQ(stage.model.body_count(), accretion.model.body_count());
    for (std::size_t b = 0; b < stage.model.body_count(); ++b) {
      EXPECT_EQ(stage.model.sphere_radius(b), accretion.model.sphere_radius(b));
      EXPECT_EQ(stage.model.mass[b], accretion.model.mass[b]);
    }
    const ContactLaw& law = stage.model.contact_laws.get(0, 0);
    EXPECT_EQ(law.friction_coefficient, std::stod(mu));
    EXPECT_EQ(law.friction_coefficient, accretion.model.contact_laws.get(0, 0).friction_coefficient);
    EXPECT_EQ(law.cohesion, std::stod(stem.substr(c_at + 2)));
    EXPECT_EQ(law.normal_restitution, 0.0);
    ASSERT_EQ(stage.initial_conditions.size(), 1u);
    const InitialCondition& spin = stage.initial_conditions[0];
    EXPECT_FALSE(spin.centre.has_value());
    EXPECT_EQ(spin.velocity, Vec3::Zero());
    EXPECT_EQ(spin.angular_velocity.head<2>(), Eigen::Vector2d::Zero());
    EXPECT_GT(spin.angular_velocity.z(), 0.0);
    EXPECT_FALSE(stage.run.until_rest);
  }
  EXPECT_EQ(stages, 6u);  // mu 0.2 and 0.6, F_c 0, 100 and 300 N
  // run.sh makes the mu = 0.6 aggregate by branching the settled mu = 0.2 one (MU06_FROM=branch):
  // the two accretions must hold the same grains.
  const Scene low = load_scene_file(folder / "accretion-mu0.2.toml");
  const Scene high = load_scene_file(folder / "accretion-mu0.6.toml");
  ASSERT_EQ(low.model.body_count(), high.model.body_count());
  for (std::size_t b = 0; b < low.model.body_count(); ++b) {
    EXPECT_EQ(low.model.sphere_radius(b), high.model.sphere_radius(b));
    EXPECT_EQ(low.model.mass[b], high.model.mass[b]);
  }
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
}  // namespace
}  // namespace rubble
