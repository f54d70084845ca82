#pragma once
// Shapes of bodies, described in the body frame (origin at the centre of mass, axes along the
// principal axes of inertia). Walls are bodies of infinite mass with a plane or box shape.
#include <cstdint>
#include <vector>

#include "core/math.hpp"

namespace rubble {

/// Which shape table a body's shape lives in.
enum class ShapeKind : std::uint8_t {
  sphere,      ///< a ball (grains)
  polyhedron,  ///< a convex polyhedron (grains)
  plane,       ///< an infinite plane (walls only)
  box,         ///< a bounded box, solid inside (walls only)
};

/// A ball of the given radius centred on the body origin.
struct Sphere {
  double radius = 0.0;  ///< m
};

/// An infinite plane through the body origin. The solid fills the half-space behind the plane,
/// grains live on the side its normal points to.
struct Plane {
  Vec3 normal = Vec3::UnitZ();  ///< unit outward normal in the body frame
};

/// A solid rectangular box centred on the body origin, aligned with the body axes.
struct Box {
  Vec3 half_extents = Vec3::Zero();  ///< m, half side lengths along the body axes
};

/// A convex polyhedron in its body frame (centroid at the origin, principal axes).
/// Faces are lists of vertex indices in counter-clockwise order seen from outside.
/// Build it with make_convex_polyhedron (core/polyhedron.hpp), which fills every field.
struct ConvexPolyhedron {
  std::vector<Vec3> vertices;                  ///< m, body frame
  std::vector<std::vector<int>> faces;         ///< vertex indices, CCW from outside
  std::vector<Vec3> face_normals;              ///< unit outward normals, one per face
  std::vector<std::pair<int, int>> edges;      ///< each undirected edge once (i < j)
  std::vector<double> face_offsets;            ///< m, d_f = max over the vertices of n_f . x (supporting plane)
  std::vector<std::pair<int, int>> edge_faces; ///< per edge: the face on its left (i -> j CCW) and on its right
  std::vector<std::vector<int>> vertex_neighbours;  ///< per vertex: the vertices sharing an edge with it
  Vec3 box_min = Vec3::Zero();                 ///< m, body-frame bounding box, lower corner
  Vec3 box_max = Vec3::Zero();                 ///< m, body-frame bounding box, upper corner
  double bounding_radius = 0.0;                ///< m, max |x| over the vertices (sphere about the centroid)
  double volume = 0.0;                         ///< m^3
  Vec3 principal_inertia_per_density = Vec3::Zero();  ///< m^5, diagonal of the inertia tensor / density
};

}  // namespace rubble
