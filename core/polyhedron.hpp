#pragma once
// Convex polyhedra: exact mass properties from the surface mesh, and the construction of the
// body-frame shape (centroid at the origin, principal axes of inertia) with its topology
// (face normals, edges, adjacency) filled in. The contact detection of polyhedra
// (contact_detection/common_plane.hpp) relies on everything make_convex_polyhedron fills.
#include <string>
#include <vector>

#include "core/input_error.hpp"
#include "core/math.hpp"
#include "core/model.hpp"
#include "core/shapes.hpp"

namespace rubble {

/// Thrown for a mesh that is not a valid convex polyhedron; says which face or vertex is at
/// fault (-1 when the fault is global) so a file reader can point at the line. An InputError:
/// the mesh is what a user gave (core/input_error.hpp).
struct PolyhedronError : InputError {
  int face = -1;    ///< index of the offending face, or -1
  int vertex = -1;  ///< index of the offending vertex, or -1
  /// The message, and the face and vertex at fault.
  PolyhedronError(const std::string& what, int face_index = -1, int vertex_index = -1)
      : InputError(what), face(face_index), vertex(vertex_index) {}
};

/// Volume, centroid and inertia of a closed polyhedral surface, for a unit density.
struct PolyhedronMassProperties {
  double volume = 0.0;                      ///< m^3
  Vec3 centroid = Vec3::Zero();             ///< m, in the frame of the input vertices
  Mat3 inertia_per_density = Mat3::Zero();  ///< m^5, inertia tensor about the centroid / density
};

/// Exact mass properties of the solid bounded by `faces` (vertex indices, counter-clockwise seen
/// from outside; polygons are fanned into triangles). The solid is split into tetrahedra (a
/// reference point, one triangle); a tetrahedron with vertices p0..p3 has volume
/// det[p1-p0, p2-p0, p3-p0]/6, first moment V (p0+p1+p2+p3)/4 and second moment
/// int x x^T dV = V/20 (sum_i p_i p_i^T + s s^T), s = sum_i p_i (Tonon 2004, J. Math. Stat. 1(1);
/// the same closed form as Mirtich 1996 for tetrahedra). The inertia about the centroid is
/// I = tr(C) Id - C with C the central second moment. Exact up to round-off for any closed,
/// consistently oriented surface, convex or not. Throws PolyhedronError on bad indices.
PolyhedronMassProperties polyhedron_mass_properties(const std::vector<Vec3>& vertices,
                                                    const std::vector<std::vector<int>>& faces);

/// The same for faces stored as flat lists (a ConvexPolyhedron's).
PolyhedronMassProperties polyhedron_mass_properties(const std::vector<Vec3>& vertices, const IndexLists& faces);

/// Options of make_convex_polyhedron.
struct PolyhedronBuildOptions {
  /// Faces may deviate from their plane, and vertices may lie outside a face's plane, by this
  /// fraction of the polyhedron's diameter before the mesh is rejected as not convex. The default
  /// tolerates coordinates written with ~7 significant digits; merged faces need more.
  double convexity_tolerance = 1e-6;
  /// Faces used for the mass properties instead of `faces` when not empty: the exact
  /// triangulation of a mesh whose merged faces are slightly bent (same vertices).
  std::vector<std::vector<int>> mass_faces;
};

/// Where the body frame sits in the frame of the input vertices: x_input = centroid + orientation x_body.
struct PolyhedronPose {
  Vec3 centroid = Vec3::Zero();         ///< m, centre of mass in the input frame
  Quat orientation = Quat::Identity();  ///< body frame (principal axes) -> input frame
};

/// Builds a convex polyhedron from a closed surface mesh: checks it (every index valid, every
/// face a polygon of >= 3 distinct vertices, every edge shared by exactly two faces with
/// opposite orientations, Euler characteristic 2, positive volume, convex within the tolerance),
/// moves the origin to the centroid and the axes to the principal axes of inertia (when the
/// inertia tensor is already diagonal or isotropic to 1e-12, the input axes are kept so a
/// cube stays axis-aligned), then fills face normals (Newell's method), supporting-plane
/// offsets, edges, edge-face and vertex adjacency, bounding box and sphere, volume and
/// principal inertia per density. `pose` (optional) receives the body frame's pose in the
/// input frame, so a shape read from a file can be placed where the file put it.
/// Throws PolyhedronError with a message saying what is wrong.
ConvexPolyhedron make_convex_polyhedron(std::vector<Vec3> vertices, std::vector<std::vector<int>> faces,
                                        const PolyhedronBuildOptions& options = {}, PolyhedronPose* pose = nullptr);

/// Releases the spare capacity of every array of `shape` (make_convex_polyhedron does it; for
/// shapes assembled by hand). A scene holds one shape per polyhedral grain, so capacity left by
/// push_back is per-grain memory.
void shrink_to_fit(ConvexPolyhedron& shape);

/// The same shape scaled by `factor` > 0 about its centroid (volume x f^3, inertia x f^5).
ConvexPolyhedron scaled_polyhedron(const ConvexPolyhedron& shape, double factor);

/// A rectangular box with the given half extents as a convex polyhedron (used for box walls).
ConvexPolyhedron make_box_polyhedron(const Vec3& half_extents);

/// Index of a vertex maximising direction . x (ties go to the lowest index; brute force, which
/// for the 10-70 vertices of a grain is as fast as hill climbing and exact for merged faces).
int support_vertex(const ConvexPolyhedron& shape, const Vec3& direction);

/// max over the vertices of direction . x: the support function h(direction).
double support_value(const ConvexPolyhedron& shape, const Vec3& direction);

/// Adds a polyhedron grain built by make_convex_polyhedron (its volume and inertia fields are
/// used) with the given material; returns its body id. The body's orientation in the state maps
/// the shape's principal frame to the world.
int add_polyhedron_grain(Model& model, ConvexPolyhedron shape, int material);

}  // namespace rubble
