// preprocessing/random_polyhedron: reproducibility, parameters, volume against CGAL, merging.
#include "preprocessing/random_polyhedron.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "core/polyhedron.hpp"

namespace rubble {
namespace {

TEST(RandomPolyhedron, SameSeedSameShapeOtherSeedOtherShape) {
  RandomPolyhedronOptions options;
  const ConvexPolyhedron a = generate_random_polyhedron(options, 42);
  const ConvexPolyhedron b = generate_random_polyhedron(options, 42);
  const ConvexPolyhedron c = generate_random_polyhedron(options, 43);
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  for (std::size_t i = 0; i < a.vertices.size(); ++i) EXPECT_EQ(a.vertices[i], b.vertices[i]);
  EXPECT_EQ(a.faces, b.faces);
  EXPECT_NE(a.volume, c.volume);
}

TEST(RandomPolyhedron, VertexCountAndShapeRatiosStayInRange) {
  RandomPolyhedronOptions options;
  options.diameter = 2.0;
  options.merge_angle_degrees = 0.0;  // every sphere point is a hull vertex
  int smallest = 1000, largest = 0;
  for (std::uint64_t seed = 0; seed < 200; ++seed) {
    const ConvexPolyhedron p = generate_random_polyhedron(options, seed);
    const int n = static_cast<int>(p.vertices.size());
    smallest = std::min(smallest, n);
    largest = std::max(largest, n);
    EXPECT_GE(n, 10);
    EXPECT_LE(n, 70);
    // Principal extents: long >= intermediate >= short >= 0.25 long (e, p >= 0.5), within the
    // slack of a finite sample of the ellipsoid's surface.
    const Vec3 extent = p.box_max - p.box_min;
    Vec3 sorted = extent;
    std::sort(sorted.data(), sorted.data() + 3);
    EXPECT_GE(sorted[0], 0.2 * sorted[2]);
    EXPECT_LE(sorted[2], 2.0 + 1e-12);  // inside the circumscribed sphere of diameter 2
  }
  EXPECT_LE(smallest, 13);  // the range is covered (200 draws uniform in [10, 70])
  EXPECT_GE(largest, 67);
}

// Reference: the smallest enclosing sphere has the requested diameter, so every vertex is
// within d/2 of its centre and the farthest pair of vertices is at most d apart but more than d/2.
TEST(RandomPolyhedron, CircumscribedDiameterIsTheRequestedOne) {
  RandomPolyhedronOptions options;
  options.diameter = 7.5;
  for (std::uint64_t seed = 0; seed < 20; ++seed) {
    const ConvexPolyhedron p = generate_random_polyhedron(options, seed);
    double farthest = 0.0;
    for (const Vec3& u : p.vertices) {
      for (const Vec3& v : p.vertices) farthest = std::max(farthest, (u - v).norm());
    }
    EXPECT_LE(farthest, 7.5 * (1 + 1e-12));
    EXPECT_GE(farthest, 7.5 * std::sqrt(3.0) / 2.0 * (1 - 1e-12));  // Jung's theorem bound
    EXPECT_GE(p.bounding_radius, 3.75 * (1 - 1e-12));
  }
}

// Reference: CGAL's own volume of the hull of the same vertices (Polygon_mesh_processing::volume).
// The mass properties come from the hull's triangles, merged faces or not: agreement to
// round-off (1e-12 relative). The stored (merged) faces, fanned, bound a surface that differs
// from the hull by slivers of (face area) x (bend): 5e-3 relative for 1 degree.
TEST(RandomPolyhedron, VolumeMatchesCgal) {
  for (double merge : {0.0, 1.0}) {
    RandomPolyhedronOptions options;
    options.merge_angle_degrees = merge;
    for (std::uint64_t seed = 100; seed < 150; ++seed) {
      const ConvexPolyhedron p = generate_random_polyhedron(options, seed);
      const double reference = convex_hull_volume(p.vertices);
      EXPECT_NEAR(p.volume, reference, 1e-12 * reference) << "seed " << seed;
      // And the mass properties recomputed from the stored mesh agree with the stored ones.
      const PolyhedronMassProperties m = polyhedron_mass_properties(p.vertices, p.faces);
      const double tolerance = merge == 0.0 ? 1e-12 : 5e-3;
      EXPECT_NEAR(m.volume, p.volume, tolerance * p.volume);
      EXPECT_NEAR(m.centroid.norm(), 0.0, tolerance);
    }
  }
}

TEST(RandomPolyhedron, MergedFacesAreNotNearlyCoplanarWithTheirSeed) {
  // After merging at 5 degrees, fewer faces than CGAL's triangles and all faces still convex.
  RandomPolyhedronOptions merged;
  merged.merge_angle_degrees = 5.0;
  merged.min_vertices = merged.max_vertices = 70;
  RandomPolyhedronOptions raw = merged;
  raw.merge_angle_degrees = 0.0;
  std::size_t fewer = 0;
  for (std::uint64_t seed = 0; seed < 20; ++seed) {
    const ConvexPolyhedron m = generate_random_polyhedron(merged, seed);
    const ConvexPolyhedron r = generate_random_polyhedron(raw, seed);
    if (m.faces.size() < r.faces.size()) ++fewer;
  }
  EXPECT_GT(fewer, 10u);
}

TEST(MergeCoplanarFaces, SubdividedCubeFaceBecomesOneSquare) {
  // A unit cube whose top face is split in 4 triangles around a centre vertex raised by 1e-4.
  std::vector<Vec3> v;
  for (int k = 0; k < 8; ++k) v.emplace_back((k & 1) ? 0.5 : -0.5, (k & 2) ? 0.5 : -0.5, (k & 4) ? 0.5 : -0.5);
  v.emplace_back(0, 0, 0.5 + 1e-4);
  std::vector<std::vector<int>> faces = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1},
                                         {4, 5, 8},    {5, 7, 8},    {7, 6, 8},    {6, 4, 8}};
  std::vector<int> interior;
  const auto merged = merge_coplanar_faces(v, faces, 1.0, interior);
  EXPECT_EQ(merged.size(), 6u);
  ASSERT_EQ(interior.size(), 1u);
  EXPECT_EQ(interior[0], 8);
  // With a 0.001 degree threshold the 4 triangles stay (their tilt is ~0.023 degrees).
  const auto kept = merge_coplanar_faces(v, faces, 0.001, interior);
  EXPECT_EQ(kept.size(), 9u);
  EXPECT_TRUE(interior.empty());
}

TEST(RandomPolyhedron, BadOptionsAreRejectedWithAClearMessage) {
  auto message = [](RandomPolyhedronOptions o) -> std::string {
    try {
      (void)generate_random_polyhedron(o, 1);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  RandomPolyhedronOptions o;
  o.min_vertices = 3;
  EXPECT_NE(message(o).find("min_vertices = 3"), std::string::npos);
  o = {};
  o.max_vertices = 5;
  EXPECT_NE(message(o).find("max_vertices"), std::string::npos);
  o = {};
  o.min_elongation = 0.0;
  EXPECT_NE(message(o).find("min_elongation"), std::string::npos);
  o = {};
  o.diameter = -1.0;
  EXPECT_NE(message(o).find("diameter"), std::string::npos);
}

TEST(ConvexHull, DegenerateInputIsAClearError) {
  const std::vector<Vec3> flat = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0.5, 0.5, 0}};
  EXPECT_THROW((void)convex_hull_triangles(flat), std::runtime_error);
  try {
    (void)convex_hull_volume(flat);
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("degenerate"), std::string::npos);
  }
}

}  // namespace
}  // namespace rubble
