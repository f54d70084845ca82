// The plane geometry of contact polygons (contact_detection/contact_polygon.hpp) against
// hand-computed shapes: a unit square with extra points, segments, the area-keeping reduction.
#include <gtest/gtest.h>

#include "contact_detection/contact_polygon.hpp"

namespace rubble::contact_polygon {
namespace {

Polygon points(std::initializer_list<Vec2> list) {
  Polygon out;
  int id = 0;
  for (const Vec2& p : list) out.push_back({p, id++});
  return out;
}

double signed_area(const Polygon& polygon) {
  double twice = 0.0;
  for (std::size_t i = 0; i < polygon.size(); ++i) twice += cross2(polygon[i].p, polygon[(i + 1) % polygon.size()].p);
  return 0.5 * twice;
}

TEST(Hull2d, SquareWithInnerAndEdgePointsKeepsItsFourCornersCounterClockwise) {
  // Corners, the centre, and the midpoint of each side (on the hull's edges: dropped).
  const Polygon hull =
      hull_2d(points({{0.5, 0.5}, {1, 1}, {0, 0}, {0.5, 0}, {1, 0}, {1, 0.5}, {0, 1}, {0.5, 1}, {0, 0.5}}), 1e-12);
  ASSERT_EQ(hull.size(), 4u);
  EXPECT_DOUBLE_EQ(signed_area(hull), 1.0);  // positive: counter-clockwise
  for (const CapVertex& c : hull) {
    EXPECT_TRUE((c.p.x() == 0.0 || c.p.x() == 1.0) && (c.p.y() == 0.0 || c.p.y() == 1.0)) << c.p.transpose();
  }
}

TEST(Hull2d, NearlyCollinearCapCollapsesToItsEndsAndCoincidentPointsKeepTheLowestId) {
  // Points 1e-9 off the x axis with a tolerance of 1e-7: a segment from 0 to 2.
  const Polygon segment = hull_2d(points({{1, 1e-9}, {0, 0}, {2, -1e-9}, {0.5, 0}}), 1e-7);
  ASSERT_EQ(segment.size(), 2u);
  EXPECT_EQ(std::min(segment[0].p.x(), segment[1].p.x()), 0.0);
  EXPECT_EQ(std::max(segment[0].p.x(), segment[1].p.x()), 2.0);
  // Three copies of one point (ids 0, 1, 2) within the tolerance: one point, id 0.
  const Polygon point = hull_2d(points({{1, 1}, {1, 1 + 1e-9}, {1 + 1e-9, 1}}), 1e-7);
  ASSERT_EQ(point.size(), 1u);
  EXPECT_EQ(point[0].vertex, 0);
}

TEST(Inside, UnitSquareWithAndWithoutTolerance) {
  const Polygon square = hull_2d(points({{0, 0}, {1, 0}, {1, 1}, {0, 1}}), 0.0);
  EXPECT_TRUE(inside(square, Vec2(0.5, 0.5), 0.0));
  EXPECT_FALSE(inside(square, Vec2(1.001, 0.5), 0.0));
  EXPECT_TRUE(inside(square, Vec2(1.001, 0.5), 0.002));
  const Polygon segment = points({{0, 0}, {2, 0}});
  EXPECT_TRUE(inside(segment, Vec2(1, 0.001), 0.002));
  EXPECT_FALSE(inside(segment, Vec2(2.01, 0), 0.002));
}

TEST(ClosestOnBoundary, EdgeInteriorGivesAnEdgeCodeAndACornerAVertexCode) {
  const Polygon square = hull_2d(points({{0, 0}, {1, 0}, {1, 1}, {0, 1}}), 0.0);
  std::uint32_t feature = 0;
  const Vec2 on_edge = closest_on_boundary(square, Vec2(2, 0.25), 4, feature);
  EXPECT_LT((on_edge - Vec2(1, 0.25)).norm(), 1e-15);
  EXPECT_EQ(feature & ~index_mask, kind_edge);
  const Vec2 at_corner = closest_on_boundary(square, Vec2(2, 3), 4, feature);
  EXPECT_LT((at_corner - Vec2(1, 1)).norm(), 1e-15);
  EXPECT_EQ(feature & ~index_mask, kind_vertex);
  // clamp_into keeps an inside point and moves an outside one onto the boundary.
  EXPECT_EQ(clamp_into(square, Vec2(0.3, 0.4)), Vec2(0.3, 0.4));
  EXPECT_LT((clamp_into(square, Vec2(-1, 0.5)) - Vec2(0, 0.5)).norm(), 1e-15);
}

TEST(SegmentsCross, CrossingPointAndParallelSegments) {
  Vec2 at;
  ASSERT_TRUE(segments_cross(Vec2(0, 0), Vec2(2, 2), Vec2(0, 2), Vec2(2, 0), at));
  EXPECT_LT((at - Vec2(1, 1)).norm(), 1e-15);
  EXPECT_FALSE(segments_cross(Vec2(0, 0), Vec2(1, 0), Vec2(0, 1), Vec2(1, 1), at));  // parallel
  EXPECT_FALSE(segments_cross(Vec2(0, 0), Vec2(1, 1), Vec2(3, 0), Vec2(2, 1), at));  // lines cross beyond the ends
}

std::vector<Candidate> grid(int n, double deepest_gap) {
  std::vector<Candidate> all;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const Vec2 p(static_cast<double>(i) / (n - 1), static_cast<double>(j) / (n - 1));
      all.push_back({p, 0.0, 0.0, 0.0, 0u, static_cast<std::uint32_t>(all.size())});
    }
  }
  all[static_cast<std::size_t>(n * n / 2)].gap = deepest_gap;  // the centre
  return all;
}

TEST(ReduceToFour, FlatSquareContactKeepsTheDeepestPointAndSpansTheLargestArea) {
  // 5 x 5 points on the unit square, the centre 1 mm deeper: the deepest point is kept first and
  // the three others span the largest area any 3 grid points reach with it. Brute force over
  // every triple gives that area independently.
  const std::vector<Candidate> all = grid(5, -1e-3);
  const std::vector<Candidate> kept = reduce_to_four(all, 1e-12);
  ASSERT_EQ(kept.size(), 4u);
  EXPECT_EQ(kept[0].feature_b, 12u);  // the centre
  Polygon kept_points;
  for (const Candidate& c : kept) kept_points.push_back({c.p, 0});
  const double area = polygon_area(kept_points);
  double best = 0.0;
  for (std::size_t i = 0; i < all.size(); ++i) {
    for (std::size_t j = i + 1; j < all.size(); ++j) {
      for (std::size_t k = j + 1; k < all.size(); ++k) {
        best = std::max(best, polygon_area({{all[12].p, 0}, {all[i].p, 1}, {all[j].p, 2}, {all[k].p, 3}}));
      }
    }
  }
  EXPECT_GT(area, 0.0);
  EXPECT_LE(area, best + 1e-15);
  EXPECT_GE(area, 0.5 * best);  // the greedy choice is within a factor 2 of the optimum here
  // Collinear candidates reduce to the segment's two ends.
  std::vector<Candidate> line;
  for (int i = 0; i < 6; ++i) line.push_back({Vec2(0.2 * i, 0.0), 0.0, 0.0, 0.0, 0u, static_cast<std::uint32_t>(i)});
  EXPECT_EQ(reduce_to_four(line, 1e-12).size(), 2u);
}

TEST(AddOffPlanePoints, AffineGapsAddNothingAConvexDipIsKept) {
  // Gaps affine over the plane (a tilted flat face): the kept corners stand for every point.
  std::vector<Candidate> all = grid(3, 0.0);
  for (Candidate& c : all) c.gap = 0.01 + 0.002 * c.p.x() - 0.001 * c.p.y();
  const std::vector<Candidate> corners = {all[0], all[2], all[6], all[8]};
  EXPECT_EQ(add_off_plane_points(all, corners, 1e-6, max_points_per_pair).size(), 4u);
  // The centre 1e-4 below the affine fit (a curved cap): it is added.
  all[4].gap -= 1e-4;
  const std::vector<Candidate> kept = add_off_plane_points(all, corners, 1e-6, max_points_per_pair);
  ASSERT_EQ(kept.size(), 5u);
  EXPECT_EQ(kept[4].feature_b, 4u);
  // ...but not with a tolerance above the dip.
  EXPECT_EQ(add_off_plane_points(all, corners, 2e-4, max_points_per_pair).size(), 4u);
}

}  // namespace
}  // namespace rubble::contact_polygon
