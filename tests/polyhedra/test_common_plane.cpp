// contact_detection/common_plane: the common plane of random polyhedra at random poses against an
// independent reference, the Minkowski difference D = B - A built by CGAL's convex hull of all
// vertex differences: the bodies are apart iff the origin is outside D; the distance is then the
// distance from the origin to D (normal = direction of its closest point), and when they
// overlap the penetration depth is the distance from the origin to the nearest facet plane of
// D (normal = minus that facet's outward normal).
#include "contact_detection/common_plane.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/polyhedron.hpp"
#include "preprocessing/random_polyhedron.hpp"

namespace rubble {
namespace {

struct Reference {
  double gap = 0.0;            // signed: distance, or -(penetration depth)
  Vec3 normal = Vec3::Zero();  // from A to B
  bool unique = true;          // the optimal normal is isolated (compare normals only then)
};

/// Closest point of triangle (a, b, c) to the origin (Voronoi regions; Ericson 2005 sec. 5.1.5).
Vec3 closest_on_triangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = -a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = -b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = -c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denominator = 1.0 / (va + vb + vc);
  return a + ab * (vb * denominator) + ac * (vc * denominator);
}

Reference minkowski_reference(const PolyhedronInWorld& a, const PolyhedronInWorld& b) {
  std::vector<Vec3> difference;
  for (const Vec3& vb : b.shape->vertices) {
    const Vec3 yb = b.rotation * vb + b.position;
    for (const Vec3& va : a.shape->vertices) difference.push_back(yb - (a.rotation * va + a.position));
  }
  const auto triangles = convex_hull_triangles(difference);
  bool inside = true;
  double nearest_plane = std::numeric_limits<double>::infinity();
  double second_plane = std::numeric_limits<double>::infinity();
  Vec3 nearest_normal = Vec3::Zero();
  double distance = std::numeric_limits<double>::infinity();
  Vec3 closest = Vec3::Zero();
  std::vector<std::pair<double, Vec3>> planes;
  for (const auto& t : triangles) {
    const Vec3& p = difference[static_cast<std::size_t>(t[0])];
    const Vec3& q = difference[static_cast<std::size_t>(t[1])];
    const Vec3& r = difference[static_cast<std::size_t>(t[2])];
    const Vec3 m = (q - p).cross(r - p).normalized();
    const double offset = m.dot(p);  // outward plane m.x = offset
    if (offset < 0.0) inside = false;
    planes.emplace_back(offset, m);
    const Vec3 c = closest_on_triangle(p, q, r);
    if (c.norm() < distance) {
      distance = c.norm();
      closest = c;
    }
  }
  Reference ref;
  if (!inside) {
    ref.gap = distance;
    ref.normal = closest.normalized();
    ref.unique = distance > 1e-6;
    return ref;
  }
  for (const auto& [offset, m] : planes) {
    if (offset < nearest_plane) {
      nearest_plane = offset;
      nearest_normal = m;
    }
  }
  // Second-best plane with a clearly different normal (coplanar facets share the same plane).
  for (const auto& [offset, m] : planes) {
    if (m.dot(nearest_normal) < 1.0 - 1e-9) second_plane = std::min(second_plane, offset);
  }
  ref.gap = -nearest_plane;
  ref.normal = -nearest_normal;
  ref.unique = second_plane - nearest_plane > 1e-6;
  return ref;
}

Quat random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  return Quat(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
}

Vec3 random_direction(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  return Vec3(normal(rng), normal(rng), normal(rng)).normalized();
}

/// What check_random_pairs met: overlapping and separated pairs, and pairs whose reference normal
/// is unique (so that the normal itself was compared).
struct PairCounts {
  int overlapping = 0, apart = 0, normals_compared = 0;
};

/// Checks `pairs` random pairs from a pool of random polyhedra (diameter d = 1) against the
/// reference. Tolerances (d = 1): classification wherever |distance| > 1e-9; gap and normal
/// 1e-6; f(normal) == gap to 1e-9 (the returned plane is the one whose separation is reported).
/// `counts` says which kinds of pairs were met, for the caller to check that both outcomes are
/// well represented.
void check_random_pairs(int pairs, int min_vertices, int max_vertices, std::uint64_t seed, PairCounts& counts) {
  RandomPolyhedronOptions options;
  options.min_vertices = min_vertices;
  options.max_vertices = max_vertices;
  options.merge_angle_degrees = 0.0;  // the reference is the hull of the vertices
  std::vector<ConvexPolyhedron> pool;
  for (std::uint64_t k = 0; k < 64; ++k) pool.push_back(generate_random_polyhedron(options, seed + k));
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, pool.size() - 1);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  int& overlapping = counts.overlapping;
  int& apart = counts.apart;
  int& normals_compared = counts.normals_compared;
  for (int k = 0; k < pairs; ++k) {
    const PolyhedronInWorld a{&pool[pick(rng)], Vec3(uniform(rng), uniform(rng), uniform(rng)),
                              random_rotation(rng).toRotationMatrix()};
    const ConvexPolyhedron& shape_b = pool[pick(rng)];
    // Centre distance uniform up to the sum of the bounding radii: about half the pairs overlap.
    const double reach = a.shape->bounding_radius + shape_b.bounding_radius;
    const PolyhedronInWorld b{&shape_b, a.position + uniform(rng) * reach * random_direction(rng),
                              random_rotation(rng).toRotationMatrix()};
    const Reference ref = minkowski_reference(a, b);
    const CommonPlane plane = find_common_plane(a, b, nullptr, std::numeric_limits<double>::infinity());
    ASSERT_TRUE(plane.complete);
    if (std::abs(ref.gap) > 1e-9) {
      ASSERT_EQ(plane.gap > 0.0, ref.gap > 0.0) << "pair " << k << " gap " << plane.gap << " reference " << ref.gap;
    }
    ASSERT_NEAR(plane.gap, ref.gap, 1e-6) << "pair " << k;
    ASSERT_NEAR(plane_separation(a, b, plane.normal), plane.gap, 1e-9) << "pair " << k;
    ASSERT_NEAR(plane.normal.norm(), 1.0, 1e-12);
    if (ref.unique) {
      ++normals_compared;
      ASSERT_LT((plane.normal - ref.normal).norm(), 1e-6) << "pair " << k << " gap " << ref.gap;
    }
    (ref.gap > 0 ? apart : overlapping)++;

    // Warm start from a perturbed normal and a finite cutoff: the same plane, or an early stop
    // that is right about the pair being beyond the cutoff.
    const Vec3 warm = (ref.normal + 0.05 * random_direction(rng)).normalized();
    const double cutoff = 0.05;
    const CommonPlane warmed = find_common_plane(a, b, &warm, cutoff);
    if (!warmed.complete) {
      ASSERT_GE(ref.gap, cutoff - 1e-9) << "pair " << k;
      ASSERT_LE(warmed.gap, ref.gap + 1e-9);
    } else {
      ASSERT_NEAR(warmed.gap, ref.gap, 1e-6) << "pair " << k;
    }
  }
}

TEST(CommonPlane, TenThousandRandomPairsMatchTheMinkowskiReference) {
  PairCounts counts;
  check_random_pairs(10000, 10, 24, 1000, counts);
  // Both outcomes are well represented, and most normals were compared.
  EXPECT_GT(counts.overlapping, 2000);
  EXPECT_GT(counts.apart, 2000);
  EXPECT_GT(counts.normals_compared, 5000);
}

TEST(CommonPlane, FullSizeRangePairsMatchTheMinkowskiReference) {
  PairCounts counts;
  check_random_pairs(600, 10, 70, 5000, counts);
  EXPECT_GT(counts.overlapping, 120);
  EXPECT_GT(counts.apart, 120);
  EXPECT_GT(counts.normals_compared, 300);
}

/// Pairs a hair apart (gap 1e-5 to 1e-2 of the diameter d = 1, the range of grains resting in
/// a deposit) warm-started from a normal near the true one: the common plane maximises f, so its
/// gap is at least f(warm start), and it matches the Minkowski reference to 1e-6. GJK converging
/// on such pairs adds a last support point almost in the plane of its triangle, and round-off in
/// that flat tetrahedron could pick a wrong face or claim the origin inside: before GJK's |v| was
/// required to decrease, pair 713 here (1.8e-5 d apart) came out overlapping by 2.0e-4 d.
TEST(CommonPlane, PairsAHairApartKeepTheirGap) {
  RandomPolyhedronOptions options;
  options.min_vertices = 10;
  options.max_vertices = 24;
  options.merge_angle_degrees = 0.0;
  std::vector<ConvexPolyhedron> pool;
  for (std::uint64_t k = 0; k < 64; ++k) pool.push_back(generate_random_polyhedron(options, 7000 + k));
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<std::size_t> pick(0, pool.size() - 1);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  int checked = 0;
  for (int k = 0; k < 2000; ++k) {
    const PolyhedronInWorld a{&pool[pick(rng)], Vec3::Zero(), random_rotation(rng).toRotationMatrix()};
    const ConvexPolyhedron& shape_b = pool[pick(rng)];
    PolyhedronInWorld b{&shape_b, (a.shape->bounding_radius + shape_b.bounding_radius) * random_direction(rng),
                        random_rotation(rng).toRotationMatrix()};
    const Reference apart = minkowski_reference(a, b);
    if (apart.gap <= 0.0) continue;
    // Moving B along the closest-points direction changes the distance by as much.
    const double target = std::pow(10.0, -5.0 + 3.0 * uniform(rng));
    b.position += (target - apart.gap) * apart.normal;
    const Reference ref = minkowski_reference(a, b);
    const Vec3 warm = (ref.normal + 1e-3 * random_direction(rng)).normalized();
    const CommonPlane plane = find_common_plane(a, b, &warm, 0.05);
    ASSERT_TRUE(plane.complete) << "pair " << k;
    ASSERT_GE(plane.gap, plane_separation(a, b, warm) - 1e-15) << "pair " << k;
    ASSERT_NEAR(plane.gap, ref.gap, 1e-6) << "pair " << k << " reference gap " << ref.gap;
    ++checked;
  }
  EXPECT_GT(checked, 1500);
}

TEST(CommonPlane, TwoCubesFaceToFace) {
  const ConvexPolyhedron cube = make_box_polyhedron(Vec3(0.5, 0.5, 0.5));
  const PolyhedronInWorld a{&cube, Vec3::Zero(), Mat3::Identity()};
  const PolyhedronInWorld b{&cube, Vec3(0.2, -0.1, 1.03), Mat3::Identity()};
  const CommonPlane plane = find_common_plane(a, b, nullptr, 1.0);
  EXPECT_NEAR(plane.gap, 0.03, 1e-12);
  EXPECT_NEAR((plane.normal - Vec3::UnitZ()).norm(), 0.0, 1e-12);
  const PolyhedronInWorld c{&cube, Vec3(0.2, -0.1, 0.98), Mat3::Identity()};
  const CommonPlane overlap = find_common_plane(a, c, nullptr, 1.0);
  EXPECT_NEAR(overlap.gap, -0.02, 1e-14);
  EXPECT_NEAR((overlap.normal - Vec3::UnitZ()).norm(), 0.0, 1e-14);
}

TEST(CommonPlane, CrossedEdgesGiveTheEdgeCrossProduct) {
  // Two cubes turned 45 degrees about x and about y: their edges meet crosswise.
  const ConvexPolyhedron cube = make_box_polyhedron(Vec3(0.5, 0.5, 0.5));
  const double half_diagonal = std::sqrt(0.5);
  const Mat3 ra = Eigen::AngleAxisd(M_PI / 4, Vec3::UnitX()).toRotationMatrix();
  const Mat3 rb = Eigen::AngleAxisd(M_PI / 4, Vec3::UnitY()).toRotationMatrix();
  const PolyhedronInWorld a{&cube, Vec3::Zero(), ra};
  // Off the centre line, so the line of centres is not already the answer.
  const PolyhedronInWorld b{&cube, Vec3(0.1, -0.05, 2 * half_diagonal - 0.01), rb};
  const CommonPlane plane = find_common_plane(a, b, nullptr, 1.0);
  EXPECT_EQ(plane.source, CommonPlaneSource::edge_edge);
  EXPECT_NEAR(plane.gap, -0.01, 1e-12);
  EXPECT_NEAR((plane.normal - Vec3::UnitZ()).norm(), 0.0, 1e-12);
}

TEST(CommonPlane, WarmStartIsKeptWhenAsGoodAndStopsEarlyWhenFar) {
  const ConvexPolyhedron cube = make_box_polyhedron(Vec3(0.5, 0.5, 0.5));
  const PolyhedronInWorld a{&cube, Vec3::Zero(), Mat3::Identity()};
  const PolyhedronInWorld b{&cube, Vec3(0, 0, 0.999), Mat3::Identity()};
  const Vec3 up = Vec3::UnitZ();
  const CommonPlane plane = find_common_plane(a, b, &up, 0.01);
  EXPECT_EQ(plane.source, CommonPlaneSource::warm_start);
  EXPECT_NEAR(plane.gap, -0.001, 1e-14);
  const PolyhedronInWorld far{&cube, Vec3(0, 0, 3), Mat3::Identity()};
  const CommonPlane early = find_common_plane(a, far, &up, 0.01);
  EXPECT_FALSE(early.complete);
  EXPECT_NEAR(early.gap, 2.0, 1e-14);
}

TEST(ClosestPointOnPolyhedron, CornerEdgeFaceAndInside) {
  const ConvexPolyhedron cube = make_box_polyhedron(Vec3(0.5, 0.5, 0.5));
  Vec3 closest;
  ASSERT_TRUE(closest_point_on_polyhedron(cube, Vec3(1, 1, 1), closest));
  EXPECT_NEAR((closest - Vec3(0.5, 0.5, 0.5)).norm(), 0.0, 1e-12);
  ASSERT_TRUE(closest_point_on_polyhedron(cube, Vec3(1, 1, 0.2), closest));
  EXPECT_NEAR((closest - Vec3(0.5, 0.5, 0.2)).norm(), 0.0, 1e-12);
  ASSERT_TRUE(closest_point_on_polyhedron(cube, Vec3(0.1, 2, 0.2), closest));
  EXPECT_NEAR((closest - Vec3(0.1, 0.5, 0.2)).norm(), 0.0, 1e-12);
  EXPECT_FALSE(closest_point_on_polyhedron(cube, Vec3(0.1, 0.2, 0.3), closest));
}

/// Points a hair outside random polyhedra (distance 1e-5 to 1e-2 of the diameter d = 1): GJK's
/// closest point (the sphere-polyhedron path) against the nearest point over the faces' triangles,
/// to 1e-9 d. A point is placed by moving it along the outward normal at its closest point, which
/// keeps that closest point.
TEST(ClosestPointOnPolyhedron, PointsAHairOutsideMatchTheNearestFacePoint) {
  RandomPolyhedronOptions options;
  options.min_vertices = 10;
  options.max_vertices = 70;
  options.merge_angle_degrees = 0.0;  // the reference is the hull's triangles
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  auto nearest_on_surface = [](const ConvexPolyhedron& shape, const Vec3& p) {
    Vec3 best = Vec3::Zero();
    double best_distance = std::numeric_limits<double>::infinity();
    for (const auto face : shape.faces) {
      const Vec3& v0 = shape.vertices[static_cast<std::size_t>(face[0])];
      for (std::size_t k = 1; k + 1 < face.size(); ++k) {
        const Vec3 c = p + closest_on_triangle(v0 - p, shape.vertices[static_cast<std::size_t>(face[k])] - p,
                                               shape.vertices[static_cast<std::size_t>(face[k + 1])] - p);
        if ((c - p).norm() < best_distance) {
          best_distance = (c - p).norm();
          best = c;
        }
      }
    }
    return best;
  };
  int checked = 0;
  for (std::uint64_t seed = 0; seed < 100; ++seed) {
    const ConvexPolyhedron shape = generate_random_polyhedron(options, 9000 + seed);
    for (int k = 0; k < 100; ++k) {
      const Vec3 start = (0.6 + 0.8 * uniform(rng)) * shape.bounding_radius * random_direction(rng);
      const Vec3 foot = nearest_on_surface(shape, start);
      Vec3 closest;
      if ((start - foot).norm() < 1e-3 || !closest_point_on_polyhedron(shape, start, closest)) continue;  // inside
      const double target = std::pow(10.0, -5.0 + 3.0 * uniform(rng));
      const Vec3 point = foot + target * (start - foot).normalized();
      ASSERT_TRUE(closest_point_on_polyhedron(shape, point, closest)) << "shape " << seed << " point " << k;
      ASSERT_NEAR((point - closest).norm(), target, 1e-9) << "shape " << seed << " point " << k;
      ++checked;
    }
  }
  EXPECT_GT(checked, 4000);
}

}  // namespace
}  // namespace rubble
