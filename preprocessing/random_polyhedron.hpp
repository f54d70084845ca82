#pragma once
// Random convex polyhedra as in the accretion study (the LMGC90 accretion paper sec. 3): n_v points drawn on the
// unit sphere (n_v uniform in [min_vertices, max_vertices]), axes scaled by the elongation and
// platyness ratios, convex hull (CGAL), nearly coplanar facets merged, rescaled so that the
// circumscribed (smallest enclosing) sphere has the requested diameter.
//
// Reproducibility: a std::mt19937_64 seeded with `seed`, its raw 64-bit output turned into
// numbers by our own formulas (not std::uniform_real_distribution, whose algorithm differs
// between standard libraries): the same seed gives the same polyhedron everywhere.
#include <array>
#include <cstdint>
#include <vector>

#include "core/math.hpp"
#include "core/shapes.hpp"

namespace rubble {

/// Parameters of generate_random_polyhedron (defaults: the accretion study's).
struct RandomPolyhedronOptions {
  int min_vertices = 10;        ///< n_v drawn uniformly in [min_vertices, max_vertices], >= 4
  int max_vertices = 70;        ///< >= min_vertices
  double min_elongation = 0.5;  ///< elongation e = (intermediate axis)/(long axis) uniform in [min, 1], (0, 1]
  double min_platyness = 0.5;   ///< platyness p = (short axis)/(intermediate axis) uniform in [min, 1], (0, 1]
  double diameter = 1.0;        ///< m, diameter of the circumscribed sphere, > 0
  /// Adjacent hull facets whose normals differ by less than this angle are merged into one
  /// planar-ish face, so a grain resting on two nearly coplanar facets does not flip between
  /// them from step to step. 0 keeps CGAL's triangles.
  double merge_angle_degrees = 1.0;
};

/// A random convex polyhedron in its principal body frame (see the file comment). Throws
/// std::invalid_argument for bad options, std::runtime_error for a degenerate hull (which needs
/// coincident or coplanar points, so never happens with the sphere sampling unless min_platyness
/// or min_elongation is tiny).
ConvexPolyhedron generate_random_polyhedron(const RandomPolyhedronOptions& options, std::uint64_t seed);

/// Triangles (indices into `points`, counter-clockwise seen from outside) of the convex hull of
/// `points`, computed by CGAL (convex_hull_3, exact predicates). Throws std::runtime_error when
/// the points do not span a volume.
std::vector<std::array<int, 3>> convex_hull_triangles(const std::vector<Vec3>& points);

/// Volume of the convex hull of `points` by CGAL (Polygon_mesh_processing::volume): an
/// independent reference for the mass properties.
double convex_hull_volume(const std::vector<Vec3>& points);

/// A ball: centre and radius.
struct Ball {
  Vec3 centre = Vec3::Zero();  ///< m
  double radius = 0.0;         ///< m
};

/// The smallest ball enclosing `points` (at least one): the circumscribed sphere of a convex
/// polyhedron given its vertices, the grain "diameter" of the accretion study. Computed by CGAL's
/// Min_sphere_of_spheres_d (Fischer & Gaertner 2003, "The smallest enclosing ball of balls"),
/// in double precision: the radius is exact up to round-off.
/// Its centre is in general not the centroid: a cone-like grain's ball is centred nearer its base.
Ball smallest_enclosing_ball(const std::vector<Vec3>& points);

/// Faces of a closed convex mesh after merging adjacent faces whose normals are within
/// `angle_degrees` of the largest face of their group (region growing from the largest faces).
/// A group is merged only when its boundary is a single loop that is convex seen along the
/// group's normal; otherwise its faces are kept. Vertices left inside a merged face (on no
/// boundary) are listed in `interior_vertices` (they are not referenced by the result).
std::vector<std::vector<int>> merge_coplanar_faces(const std::vector<Vec3>& vertices,
                                                   const std::vector<std::vector<int>>& faces, double angle_degrees,
                                                   std::vector<int>& interior_vertices);

}  // namespace rubble
