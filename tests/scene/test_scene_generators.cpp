// Tests of the grain generators and listed bodies (simulation/scene_generators.cpp,
// scene_bodies.cpp): cubic-grid polyhedra inside their cells, the sphere/polyhedron mix and its
// seed, random and listed vertices, sphere clouds with monodisperse sizes and size bins.
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

}  // namespace
}  // namespace rubble
