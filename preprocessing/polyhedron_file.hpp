#pragma once
// Convex polyhedra read from mesh files: OFF (Object File Format: "OFF", counts, vertices, faces
// "k i1 ... ik") and Wavefront OBJ ("v x y z", "f i j k ..." with 1-based or negative indices,
// "i/t/n" forms accepted; other statements ignored).
#include <string>

#include "core/polyhedron.hpp"
#include "core/shapes.hpp"

namespace rubble {

/// Most vertices a polyhedron file may hold (faces: twice as many). A grain's narrow phase and
/// support queries cost O(vertices); 10^6 is far beyond any grain shape and keeps a file's mesh
/// and checks within seconds and ~0.5 GB. Files are also capped at 64 MiB (core/input_file.hpp).
inline constexpr long max_polyhedron_file_vertices = 1'000'000;

/// Options of load_polyhedron_file.
struct PolyhedronFileOptions {
  /// Adjacent faces whose normals differ by less than this are merged into one face (a cube
  /// exported as 12 triangles becomes 6 squares); vertices left inside a merged face are dropped.
  double merge_angle_degrees = 0.01;
  /// Scale factor applied to the file's coordinates (e.g. 1e-3 for a file in millimetres).
  double scale = 1.0;
};

/// Reads a convex polyhedron from an .off or .obj file (by extension, case-insensitive), builds
/// it with make_convex_polyhedron (clockwise files are turned around), and returns it in its
/// principal body frame. `pose` (optional) receives where that frame sits in the file's frame,
/// so the grain can be placed where the file put it. Throws std::runtime_error whose message
/// starts with "file:line: " (the line of the offending statement, or of the first face for
/// a fault of the whole mesh).
ConvexPolyhedron load_polyhedron_file(const std::string& path, const PolyhedronFileOptions& options = {},
                                      PolyhedronPose* pose = nullptr);

}  // namespace rubble
