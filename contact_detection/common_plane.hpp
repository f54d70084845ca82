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
#include <array>
#include <cstddef>
#include <vector>

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

/// Two polyhedra seen from A's body frame, where the common-plane search and the contact points
/// both work: B's pose relative to A and, once find_common_plane has passed its warm start, B's
/// vertices and face normals moved there. Built once per pair and read by both stages, so B is moved once
/// (it was moved twice, once by each stage). The buffers at the end are the separating-axis
/// search's working space: a caller that reuses one PolyhedronPair from pair to pair (one per
/// thread) allocates nothing once they have grown.
struct PolyhedronPair {
  const ConvexPolyhedron* A = nullptr;      ///< body-frame shape of A
  const ConvexPolyhedron* B = nullptr;      ///< body-frame shape of B
  Mat3 rotation_a = Mat3::Identity();       ///< A's body frame -> world frame
  Vec3 position_a = Vec3::Zero();           ///< m, world position of A's origin (centroid)
  Mat3 rotation = Mat3::Identity();         ///< B's body frame -> A's body frame
  Vec3 translation = Vec3::Zero();          ///< m, B's origin in A's frame
  std::vector<Vec3> vb;                     ///< m, B's vertices in A's frame
  std::vector<Vec3> nb;                     ///< B's face normals in A's frame
  std::vector<double> heights_a;            ///< buffer: m, A's vertices' heights along the best normal (edge pruning)
  std::vector<double> heights_b;            ///< buffer: m, B's vertices' heights along the best normal (edge pruning)
  std::vector<Vec3> va_in_b;                ///< buffer: m, A's vertices in B's frame (edge pruning)
  std::vector<unsigned char> outcodes_a;    ///< buffer: per vertex of A, sides of B's inflated box it lies beyond
  std::vector<unsigned char> outcodes_b;    ///< buffer: per vertex of B, sides of A's inflated box it lies beyond
  std::vector<int> edges_a;                 ///< buffer: edges of A within reach of B
  std::vector<int> edges_b;                 ///< buffer: edges of B within reach of A
  std::vector<std::array<Vec3, 3>> arcs_b;  ///< buffer: Gauss-map arcs of those edges of B
};

/// Sets `pair` to A and B (B's pose in A's frame; B's vertices are moved later, only when the
/// search needs them). Keeps the pair's buffers.
void place_pair(const PolyhedronInWorld& a, const PolyhedronInWorld& b, PolyhedronPair& pair);

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

/// The same search on a pair set by `place_pair`, with the pair's buffers: B's vertices are moved
/// into A's frame (pair.vb) unless the warm start ends the search, and the contact points of the
/// pair can then read them without moving B again. Same result to the bit as the overload above.
CommonPlane find_common_plane(PolyhedronPair& pair, const Vec3* initial_normal, double cutoff);

/// Closest point of a polyhedron to `point` (both in the body frame), by GJK. Returns false when
/// the point is inside the polyhedron or on its surface within round-off (`closest` untouched).
bool closest_point_on_polyhedron(const ConvexPolyhedron& shape, const Vec3& point, Vec3& closest);

}  // namespace rubble
