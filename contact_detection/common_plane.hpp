#pragma once
// The common plane of two convex polyhedra (Cundall 1988; the LMGC90 accretion paper, section 2.2): the plane that
// best separates them. For a unit normal n (from A to B) the separation along n is
//   f(n) = min_{y in B} n.y - max_{x in A} n.x,
// and the common plane is the maximiser of f over unit vectors. When the bodies are apart the
// maximum is their distance and n the direction of the closest points; when they overlap it is
// minus the penetration depth and n the direction of least penetration.
//
// Cundall iterates on n by perturbations from the line of centres. Here the maximiser is found
// exactly (see contact_detection/README.md, "Polyhedra: common plane"):
//   1. f at the warm-start normal (last step's plane, or the line of centres); if it is already
//      beyond the cutoff (the alert distance) the pair is apart: stop.
//   2. Separating-axis search over the candidates that can carry the maximum of f for
//      polytopes: the face normals of A and B, and the cross products of the edge pairs that
//      form a face of the Minkowski difference (their arcs cross on the Gauss map, Gregorius
//      2013). Faces and edges that cannot beat the current best are pruned with the bounding
//      boxes, so a good warm start makes the search cheap.
//   3. If the best candidate separates the bodies (f > 0), the distance is refined by GJK
//      (Gilbert, Johnson, Keerthi 1988) started from that normal, which finds the closest-points
//      direction exactly (vertex-vertex and vertex-edge cases are not SAT candidates).
#include <cstddef>

#include "core/math.hpp"
#include "core/shapes.hpp"

namespace rubble {

/// A convex polyhedron placed in the world.
struct PolyhedronInWorld {
  const ConvexPolyhedron* shape = nullptr;  ///< body-frame shape
  Vec3 position = Vec3::Zero();             ///< m, world position of the body origin (centroid)
  Mat3 rotation = Mat3::Identity();         ///< body frame -> world frame
};

/// How the common plane was found (for statistics and tests).
enum class CommonPlaneSource : unsigned char {
  warm_start,      ///< the initial normal was kept (already beyond the cutoff, or as good as the best)
  face_a,          ///< a face normal of A
  face_b,          ///< a face normal of B (negated)
  edge_edge,       ///< the cross product of an edge of A and an edge of B
  closest_points,  ///< GJK closest-points direction (separated bodies)
};

/// The result of find_common_plane.
struct CommonPlane {
  Vec3 normal = Vec3::UnitZ();  ///< unit, world frame, from A to B
  double gap = 0.0;             ///< m, f(normal): separation along the normal (< 0 when overlapping)
  /// False when the search stopped early because f(initial normal) >= cutoff: `gap` is then only
  /// a lower bound of the true separation (the bodies are at least that far apart).
  bool complete = true;
  CommonPlaneSource source = CommonPlaneSource::warm_start;  ///< which candidate won
};

/// The separation f(n) = min_B n.y - max_A n.x along the world unit vector n (from A to B).
double plane_separation(const PolyhedronInWorld& a, const PolyhedronInWorld& b, const Vec3& normal);

/// The common plane of A and B. `initial_normal` (world, unit; may be null, then the line of
/// centres is used) warm-starts the search; when the bodies are apart by at least `cutoff`
/// along it, the search stops at once (complete = false). Otherwise the result is exact: when
/// overlapping, gap = -(penetration depth) and normal its direction; when apart, gap = distance
/// and normal the closest-points direction. If the initial normal is within 1e-9 x size of the
/// optimum it is kept, so a persistent contact does not flip between equivalent planes.
CommonPlane find_common_plane(const PolyhedronInWorld& a, const PolyhedronInWorld& b, const Vec3* initial_normal,
                              double cutoff);

/// Closest point of a polyhedron to `point` (both in the body frame), by GJK. Returns false when
/// the point is inside the polyhedron or on its surface within round-off (`closest` untouched).
bool closest_point_on_polyhedron(const ConvexPolyhedron& shape, const Vec3& point, Vec3& closest);

}  // namespace rubble
