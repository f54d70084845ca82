#pragma once
// The plane geometry of a contact between two polyhedra, on their common plane: the convex
// polygons of the caps' projections, their intersection, and the reduction of the candidate
// points to the few that carry the contact (used by narrow_phase_polyhedra.cpp). Plane
// coordinates are along the plane's tangents (t, s); heights along its normal n.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/math.hpp"

namespace rubble::contact_polygon {

using Vec2 = Eigen::Vector2d;

// Feature codes of contact ids: the kind in the top two bits, an index below.
constexpr std::uint32_t kind_vertex = 0u << 30;
constexpr std::uint32_t kind_edge = 1u << 30;
constexpr std::uint32_t kind_face = 2u << 30;
constexpr std::uint32_t index_mask = (1u << 30) - 1u;

/// Contact points of one pair at most: 4 for a flat contact, more only where a curved cap's
/// gap is not affine over the plane (see add_off_plane_points).
constexpr std::size_t max_points_per_pair = 8;

/// The feature code of vertex v.
inline std::uint32_t vertex_code(int v) { return kind_vertex | (static_cast<std::uint32_t>(v) & index_mask); }
/// The feature code of face f.
inline std::uint32_t face_code(int f) { return kind_face | (static_cast<std::uint32_t>(f) & index_mask); }
/// An edge between vertices i and j of a polyhedron with n vertices (any pair: the edge of a
/// contact polygon may be a chord of a nearly flat cap).
inline std::uint32_t edge_code(int i, int j, std::size_t n) {
  const auto lo = static_cast<std::uint64_t>(std::min(i, j));
  const auto hi = static_cast<std::uint64_t>(std::max(i, j));
  return kind_edge | static_cast<std::uint32_t>((lo * n + hi) & index_mask);
}

/// The z component of the cross product of two plane vectors.
inline double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// A vertex of a contact polygon: its plane coordinates and the polyhedron vertex it comes from.
struct CapVertex {
  Vec2 p;          ///< m, plane coordinates
  int vertex = 0;  ///< the polyhedron's vertex index
};

/// A convex polygon (counter-clockwise), a segment (2 vertices) or a point (1).
using Polygon = std::vector<CapVertex>;

/// Working space of hull_2d, reused from call to call so that a hull allocates nothing.
struct HullBuffers {
  Polygon unique;  ///< the sorted points with coincident ones merged
};

/// Convex hull (counter-clockwise, Andrew's monotone chain) of the cap's projections; points
/// closer than `tolerance` to a hull edge's line are dropped, so a flat cap collapses to a
/// segment (2 points) or a point (1).
Polygon hull_2d(Polygon points, double tolerance);

/// The same hull written into `hull`, with caller-owned buffers (`points` is sorted in place).
void hull_2d(Polygon& points, double tolerance, Polygon& hull, HullBuffers& buffers);

/// Is q inside the convex polygon (or on the segment / at the point) within `tolerance`?
inline bool inside(const Polygon& polygon, const Vec2& q, double tolerance) {
  if (polygon.size() == 1) return (q - polygon[0].p).norm() <= tolerance;
  if (polygon.size() == 2) {
    const Vec2 d = polygon[1].p - polygon[0].p;
    const double t = std::clamp((q - polygon[0].p).dot(d) / d.squaredNorm(), 0.0, 1.0);
    return (polygon[0].p + t * d - q).norm() <= tolerance;
  }
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Vec2& a = polygon[i].p;
    const Vec2& b = polygon[(i + 1) % polygon.size()].p;
    const Vec2 e = b - a;
    if (cross2(e, q - a) < -tolerance * e.norm()) return false;
  }
  return true;
}

/// Closest point to q on the boundary of `polygon` (a point, segment or polygon), with its feature
/// code (vertex or edge of a body with `vertex_count` vertices).
Vec2 closest_on_boundary(const Polygon& polygon, const Vec2& q, std::size_t vertex_count, std::uint32_t& feature);

/// q itself when it lies in `polygon`, else the closest point of the polygon. A vertex accepted
/// as "inside" within the feature tolerance lies just beyond the other body's footprint, where
/// that body's surface height would come from a nearly parallel side face (height ~ offset /
/// tiny slope, i.e. a huge bogus gap); its height is read at the footprint's edge instead.
Vec2 clamp_into(const Polygon& polygon, const Vec2& q);

/// Proper crossing of segments a0-a1 and b0-b1 (parallel segments never cross: their overlap is
/// found through the endpoint-inside tests); `at` receives the crossing point.
inline bool segments_cross(const Vec2& a0, const Vec2& a1, const Vec2& b0, const Vec2& b1, Vec2& at) {
  const Vec2 r = a1 - a0;
  const Vec2 s = b1 - b0;
  const double denominator = cross2(r, s);
  // |r x s| <= 1e-12 |r| |s| compared squared: no square roots on this hot path.
  if (denominator * denominator <= 1e-24 * r.squaredNorm() * s.squaredNorm()) return false;
  const Vec2 w = b0 - a0;
  const double t = cross2(w, s) / denominator;
  const double u = cross2(w, r) / denominator;
  // One branch for the four bounds (& rather than ||): which bound fails is not predictable.
  if (!(static_cast<int>(t >= 0.0) & static_cast<int>(t <= 1.0) & static_cast<int>(u >= 0.0) &
        static_cast<int>(u <= 1.0)))
    return false;
  at = a0 + t * r;
  return true;
}

/// A candidate contact point on the common plane.
struct Candidate {
  Vec2 p;                       ///< plane coordinates
  double gap = 0.0;             ///< local gap
  double height_a = 0.0;        ///< height of A's surface along n
  double height_b = 0.0;        ///< height of B's surface along n
  std::uint32_t feature_a = 0;  ///< feature code on A
  std::uint32_t feature_b = 0;  ///< feature code on B
};

/// The area of the convex hull of `points`, m^2.
double polygon_area(Polygon points);

/// Working space of add_off_plane_points, reused from pair to pair.
struct ReductionBuffers {
  std::vector<std::pair<double, std::size_t>> deficits;  ///< add_off_plane_points' candidates
};

/// Keeps at most 4 candidates carrying the contact area: the deepest point first, then the
/// point farthest from it, then the one spanning the largest triangle with them, then the one
/// adding the most area (dropped when it adds nothing). Deterministic for a given input order.
std::vector<Candidate> reduce_to_four(const std::vector<Candidate>& all, double area_tolerance);

/// The same reduction written into `kept` (its capacity reused from pair to pair).
void reduce_to_four(const std::vector<Candidate>& all, double area_tolerance, std::vector<Candidate>& kept);

/// The points `reduce_to_four` dropped that the kept ones do not stand for. A rigid relative
/// motion changes the gap affinely over the plane, so constraints at the kept points hold every
/// point whose gap lies on the affine fit of the kept points' gaps (a flat face-face contact: all
/// of them). A curved cap's gap is convex, below that fit between kinks, and a point deeper than
/// the fit by more than `tolerance` could sink by that much within one step: it is kept too,
/// deepest deficit first, up to `max_points` in all.
std::vector<Candidate> add_off_plane_points(const std::vector<Candidate>& all, std::vector<Candidate> kept,
                                            double tolerance, std::size_t max_points);

/// The same, appending to `kept` in place, with caller-owned buffers.
void add_off_plane_points(const std::vector<Candidate>& all, std::vector<Candidate>& kept, double tolerance,
                          std::size_t max_points, ReductionBuffers& buffers);

}  // namespace rubble::contact_polygon
