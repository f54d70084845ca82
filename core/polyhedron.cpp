#include "core/polyhedron.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/convex_hull_3.h>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cstdint>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <tuple>

namespace rubble {
namespace {

[[noreturn]] void fail(const std::string& what, int face = -1, int vertex = -1) {
  throw PolyhedronError("convex polyhedron: " + what, face, vertex);
}

template <typename Faces>
void check_indices(const std::vector<Vec3>& vertices, const Faces& faces) {
  const int n = static_cast<int>(vertices.size());
  for (std::size_t f = 0; f < faces.size(); ++f) {
    if (faces[f].size() < 3) fail("face " + std::to_string(f) + " has fewer than 3 vertices", static_cast<int>(f));
    for (int v : faces[f]) {
      if (v < 0 || v >= n) {
        fail("face " + std::to_string(f) + " uses vertex " + std::to_string(v) + ", expected 0.." +
                 std::to_string(n - 1),
             static_cast<int>(f));
      }
    }
  }
}

/// Vertices at which the convexity check switches from comparing every face with every vertex
/// (O(F V), fastest for grain-sized shapes: 10-70 vertices) to the hull walk below (O(V log V)).
/// Shapes under it are checked exactly as before, bit for bit.
constexpr std::size_t hull_check_min_vertices = 256;

/// The vertex graph of the convex hull of a point set, in input indices: what a linear function's
/// maximum over the points needs. On a convex polytope a vertex no neighbour of which is higher
/// is the highest vertex of all (the simplex method's principle), so the maximum is found by
/// walking uphill from any vertex, in O(path) instead of O(V).
struct HullGraph {
  std::vector<int> vertex;           ///< input index of hull vertex k
  std::vector<int> hull_index;       ///< per input vertex: its hull vertex, or -1 (not extreme)
  std::vector<std::size_t> offsets;  ///< hull vertex k's neighbours are neighbours[offsets[k] .. offsets[k+1])
  std::vector<int> neighbours;       ///< hull vertex indices
};

/// CGAL's convex hull (exact predicates, so the hull's combinatorics are right for any input)
/// of the vertices, as a HullGraph. O(V log V).
HullGraph hull_graph(const std::vector<Vec3>& vertices) {
  using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Point = Kernel::Point_3;
  using Mesh = CGAL::Surface_mesh<Point>;
  std::vector<Point> points;
  points.reserve(vertices.size());
  for (const Vec3& v : vertices) points.emplace_back(v.x(), v.y(), v.z());
  Mesh mesh;
  CGAL::convex_hull_3(points.begin(), points.end(), mesh);
  // Hull points are copies of input points: find their input indices by exact coordinates.
  std::vector<int> order(vertices.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  const auto key = [&](int i) {
    const Vec3& v = vertices[static_cast<std::size_t>(i)];
    return std::make_tuple(v.x(), v.y(), v.z());
  };
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return std::make_pair(key(a), a) < std::make_pair(key(b), b); });
  HullGraph graph;
  graph.hull_index.assign(vertices.size(), -1);
  std::vector<int> index_of(mesh.number_of_vertices() + mesh.number_of_removed_vertices(), -1);
  for (const Mesh::Vertex_index v : mesh.vertices()) {
    const Point& p = mesh.point(v);
    const auto target = std::make_tuple(p.x(), p.y(), p.z());
    const auto it = std::lower_bound(order.begin(), order.end(), target,
                                     [&](int i, const std::tuple<double, double, double>& t) { return key(i) < t; });
    if (it == order.end() || key(*it) != target) continue;  // cannot happen: hull points are input points
    index_of[static_cast<std::size_t>(v.idx())] = static_cast<int>(graph.vertex.size());
    graph.hull_index[static_cast<std::size_t>(*it)] = static_cast<int>(graph.vertex.size());
    graph.vertex.push_back(*it);
  }
  graph.offsets.assign(graph.vertex.size() + 1, 0);
  for (const Mesh::Vertex_index v : mesh.vertices()) {
    const int k = index_of[static_cast<std::size_t>(v.idx())];
    if (k < 0) continue;
    for (const Mesh::Vertex_index w : CGAL::vertices_around_target(mesh.halfedge(v), mesh)) {
      if (index_of[static_cast<std::size_t>(w.idx())] >= 0)
        graph.neighbours.push_back(index_of[static_cast<std::size_t>(w.idx())]);
    }
    graph.offsets[static_cast<std::size_t>(k) + 1] = graph.neighbours.size();
  }
  return graph;
}

/// The vertex (input index) of highest n . v over all vertices, walking uphill on the hull from
/// `start` (an input vertex; any hull vertex if it is not on the hull).
int highest_vertex(const HullGraph& hull, const std::vector<Vec3>& vertices, const Vec3& n, int start) {
  if (hull.vertex.empty()) return start;
  int k = hull.hull_index[static_cast<std::size_t>(start)];
  if (k < 0) k = 0;
  double value = n.dot(vertices[static_cast<std::size_t>(hull.vertex[static_cast<std::size_t>(k)])]);
  for (bool moved = true; moved;) {
    moved = false;
    for (std::size_t e = hull.offsets[static_cast<std::size_t>(k)]; e < hull.offsets[static_cast<std::size_t>(k) + 1];
         ++e) {
      const int next = hull.neighbours[e];
      const double h = n.dot(vertices[static_cast<std::size_t>(hull.vertex[static_cast<std::size_t>(next)])]);
      if (h > value) {  // strictly uphill: the walk ends
        value = h;
        k = next;
        moved = true;
        break;
      }
    }
  }
  return hull.vertex[static_cast<std::size_t>(k)];
}

/// Newell's normal of a polygon (robust for slightly non-planar polygons), not normalised:
/// its length is twice the projected area.
Vec3 newell_normal(const std::vector<Vec3>& vertices, std::span<const int> face) {
  Vec3 n = Vec3::Zero();
  for (std::size_t i = 0; i < face.size(); ++i) {
    const Vec3& p = vertices[static_cast<std::size_t>(face[i])];
    const Vec3& q = vertices[static_cast<std::size_t>(face[(i + 1) % face.size()])];
    n += p.cross(q);
  }
  return n;
}

/// Rotation whose columns are the principal axes of `inertia` (right-handed), or the identity
/// when the tensor is already diagonal (so aligned inputs keep their axes).
Mat3 principal_axes(const Mat3& inertia) {
  const double scale = inertia.diagonal().cwiseAbs().maxCoeff();
  const double off = std::max({std::abs(inertia(0, 1)), std::abs(inertia(0, 2)), std::abs(inertia(1, 2))});
  if (off <= 1e-12 * scale) return Mat3::Identity();
  Eigen::SelfAdjointEigenSolver<Mat3> solver(inertia);
  Mat3 axes = solver.eigenvectors();
  if (axes.determinant() < 0.0) axes.col(2) = -axes.col(2);
  return axes;
}

/// polyhedron_mass_properties for faces stored either way (nested vectors or IndexLists).
template <typename Faces>
PolyhedronMassProperties mass_properties(const std::vector<Vec3>& vertices, const Faces& faces) {
  check_indices(vertices, faces);
  PolyhedronMassProperties out;
  if (vertices.empty()) return out;
  // Reference point: the vertex mean, so the tetrahedra are small and round-off stays relative
  // to the polyhedron's size, not to its distance from the origin.
  Vec3 reference = Vec3::Zero();
  for (const Vec3& v : vertices) reference += v;
  reference /= static_cast<double>(vertices.size());

  double volume = 0.0;
  Vec3 first = Vec3::Zero();
  Mat3 second = Mat3::Zero();
  for (const auto& face : faces) {
    const Vec3 p1 = vertices[static_cast<std::size_t>(face[0])] - reference;
    for (std::size_t k = 1; k + 1 < face.size(); ++k) {
      const Vec3 p2 = vertices[static_cast<std::size_t>(face[k])] - reference;
      const Vec3 p3 = vertices[static_cast<std::size_t>(face[k + 1])] - reference;
      const double v = p1.dot(p2.cross(p3)) / 6.0;  // signed volume of (reference, p1, p2, p3)
      const Vec3 s = p1 + p2 + p3;                  // p0 = 0
      volume += v;
      first += v * s / 4.0;
      second += v / 20.0 * (p1 * p1.transpose() + p2 * p2.transpose() + p3 * p3.transpose() + s * s.transpose());
    }
  }
  out.volume = volume;
  if (volume == 0.0) return out;
  const Vec3 centroid = first / volume;
  const Mat3 central = second - volume * centroid * centroid.transpose();  // parallel axis theorem
  out.centroid = reference + centroid;
  out.inertia_per_density = central.trace() * Mat3::Identity() - central;
  return out;
}

/// The checks that need no geometry: at least 4 vertices and 4 faces, every index in range,
/// every coordinate finite.
void check_counts(const std::vector<Vec3>& vertices, const std::vector<std::vector<int>>& faces) {
  if (vertices.size() < 4) fail("needs at least 4 vertices, got " + std::to_string(vertices.size()));
  if (faces.size() < 4) fail("needs at least 4 faces, got " + std::to_string(faces.size()));
  check_indices(vertices, faces);
  for (const Vec3& v : vertices) {
    if (!v.allFinite()) fail("a vertex coordinate is not finite");  // checked by readers first
  }
}

/// An edge of a face, in the face's (counter-clockwise) order.
struct DirectedEdge {
  int from, to, face;
};

/// Every directed edge of the faces, sorted by (from, to). Fails on a face that repeats a vertex,
/// a vertex on no face, and an edge used twice in the same direction (inconsistent orientation or
/// non-manifold).
std::vector<DirectedEdge> sorted_directed_edges(std::size_t vertex_count, const std::vector<std::vector<int>>& faces) {
  std::vector<DirectedEdge> directed;
  std::vector<char> used(vertex_count, 0);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const auto& face = faces[f];
    for (std::size_t i = 0; i < face.size(); ++i) {
      const int from = face[i];
      const int to = face[(i + 1) % face.size()];
      if (from == to)
        fail("face " + std::to_string(f) + " repeats vertex " + std::to_string(from), static_cast<int>(f));
      directed.push_back({from, to, static_cast<int>(f)});
      used[static_cast<std::size_t>(from)] = 1;
    }
  }
  for (std::size_t v = 0; v < vertex_count; ++v) {
    if (!used[v]) fail("vertex " + std::to_string(v) + " is on no face", -1, static_cast<int>(v));
  }
  std::sort(directed.begin(), directed.end(), [](const DirectedEdge& x, const DirectedEdge& y) {
    return std::tie(x.from, x.to) < std::tie(y.from, y.to);
  });
  for (std::size_t i = 1; i < directed.size(); ++i) {
    if (directed[i].from == directed[i - 1].from && directed[i].to == directed[i - 1].to) {
      fail("edge " + std::to_string(directed[i].from) + "-" + std::to_string(directed[i].to) +
               " is used twice in the same direction (faces " + std::to_string(directed[i - 1].face) + " and " +
               std::to_string(directed[i].face) + "): inconsistent orientation or non-manifold",
           directed[i].face);
    }
  }
  return directed;
}

/// The undirected edges (i < j) and the two faces of each.
struct MeshEdges {
  std::vector<std::pair<int, int>> edges;       ///< vertex pairs, i < j
  std::vector<std::pair<int, int>> edge_faces;  ///< the face of i -> j, then the face of j -> i
};

/// Pairs every directed edge with its reverse: the surface is a closed, oriented 2-manifold when
/// each has one, and a sphere when V - E + F = 2 (Euler). Fails otherwise.
MeshEdges paired_edges(const std::vector<DirectedEdge>& directed, std::size_t vertex_count, std::size_t face_count) {
  auto find_directed = [&](int from, int to) -> const DirectedEdge* {
    auto it = std::lower_bound(directed.begin(), directed.end(), std::make_pair(from, to),
                               [](const DirectedEdge& e, const std::pair<int, int>& key) {
                                 return std::tie(e.from, e.to) < std::tie(key.first, key.second);
                               });
    return (it != directed.end() && it->from == from && it->to == to) ? &*it : nullptr;
  };
  MeshEdges out;
  for (const DirectedEdge& e : directed) {
    const DirectedEdge* reverse = find_directed(e.to, e.from);
    if (reverse == nullptr) {
      fail("edge " + std::to_string(e.from) + "-" + std::to_string(e.to) + " of face " + std::to_string(e.face) +
               " has no neighbouring face: the surface is not closed",
           e.face);
    }
    if (e.from < e.to) {
      out.edges.emplace_back(e.from, e.to);
      out.edge_faces.emplace_back(e.face, reverse->face);
    }
  }
  const long euler =
      static_cast<long>(vertex_count) - static_cast<long>(out.edges.size()) + static_cast<long>(face_count);
  if (euler != 2) fail("Euler characteristic V - E + F = " + std::to_string(euler) + ", expected 2 (a sphere)");
  return out;
}

/// Volume and principal inertia per density of the solid, once in its body frame.
struct BodyFrameMass {
  double volume = 0.0;                                ///< m^3
  Vec3 principal_inertia_per_density = Vec3::Zero();  ///< m^5
};

/// Moves `vertices` to the body frame (centroid at the origin, principal axes of inertia along
/// x, y, z) and sets `pose` (when given) to that frame's pose in the input's. The mass properties
/// come from `options.mass_faces` when given. Fails on a flat, empty or inside-out solid.
BodyFrameMass move_to_body_frame(std::vector<Vec3>& vertices, const std::vector<std::vector<int>>& faces,
                                 const PolyhedronBuildOptions& options, PolyhedronPose* pose) {
  const PolyhedronMassProperties mass =
      polyhedron_mass_properties(vertices, options.mass_faces.empty() ? faces : options.mass_faces);
  double extent = 0.0;
  for (const Vec3& v : vertices) extent = std::max(extent, (v - mass.centroid).norm());
  if (!(mass.volume > 1e-12 * std::pow(2.0 * extent, 3))) {
    if (mass.volume < 0.0) fail("negative volume: faces are ordered clockwise seen from outside");
    fail("degenerate (flat or empty) polyhedron: volume " + std::to_string(mass.volume));
  }
  const Mat3 axes = principal_axes(mass.inertia_per_density);
  for (Vec3& v : vertices) v = axes.transpose() * (v - mass.centroid);
  const Mat3 principal = axes.transpose() * mass.inertia_per_density * axes;
  if (pose != nullptr) {
    pose->centroid = mass.centroid;
    pose->orientation = Quat(axes).normalized();
  }
  return {mass.volume, principal.diagonal()};
}

/// The bounding sphere (about the origin) and the axis-aligned bounding box of the vertices.
void set_bounds(ConvexPolyhedron& shape) {
  shape.bounding_radius = 0.0;
  shape.box_min = Vec3::Constant(std::numeric_limits<double>::infinity());
  shape.box_max = -shape.box_min;
  for (const Vec3& v : shape.vertices) {
    shape.bounding_radius = std::max(shape.bounding_radius, v.norm());
    shape.box_min = shape.box_min.cwiseMin(v);
    shape.box_max = shape.box_max.cwiseMax(v);
  }
}

/// Checks that face f, of unit normal n and mean height `own` along it, is planar and a convex
/// polygon (it turns left at every corner seen from outside), within `tolerance` (m).
void check_face_polygon(const ConvexPolyhedron& shape, std::size_t f, const Vec3& n, double own, double tolerance) {
  const auto& face = shape.faces[f];
  for (std::size_t i = 0; i < face.size(); ++i) {
    const Vec3& p = shape.vertices[static_cast<std::size_t>(face[i])];
    const Vec3& q = shape.vertices[static_cast<std::size_t>(face[(i + 1) % face.size()])];
    const Vec3& r = shape.vertices[static_cast<std::size_t>(face[(i + 2) % face.size()])];
    if (n.dot(p) < own - tolerance) {
      fail("face " + std::to_string(f) + " is not planar: vertex " + std::to_string(face[i]) + " is " +
               std::to_string(own - n.dot(p)) + " m below its plane",
           static_cast<int>(f));
    }
    if (n.dot((q - p).cross(r - q)) < -tolerance * (q - p).norm()) {
      fail("face " + std::to_string(f) + " is not a convex polygon at vertex " +
               std::to_string(face[(i + 1) % face.size()]),
           static_cast<int>(f));
    }
  }
}

/// Appends face f's unit normal (Newell) and supporting-plane offset (the highest n . v over all
/// vertices) to the shape, after checking that the face has an area, that no vertex lies above its
/// plane by more than `tolerance` (convexity) and that the face is a planar convex polygon.
/// With `use_hull`, the highest vertex is found by walking uphill on `hull` instead of scanning all
/// vertices (large meshes; the check and the offset are the same).
void add_face_plane(ConvexPolyhedron& shape, std::size_t f, const HullGraph& hull, bool use_hull, double tolerance) {
  const auto& face = shape.faces[f];
  const Vec3 area_normal = newell_normal(shape.vertices, face);
  if (!(area_normal.norm() > 1e-14 * shape.bounding_radius * shape.bounding_radius)) {
    fail("face " + std::to_string(f) + " has zero area", static_cast<int>(f));
  }
  const Vec3 n = area_normal.normalized();
  double own = 0.0;
  for (int v : face) own += n.dot(shape.vertices[static_cast<std::size_t>(v)]);
  own /= static_cast<double>(face.size());
  double offset = -std::numeric_limits<double>::infinity();
  const auto check_vertex = [&](std::size_t v) {
    const double h = n.dot(shape.vertices[v]);
    if (h > own + tolerance) {
      fail("not convex: vertex " + std::to_string(v) + " lies " + std::to_string(h - own) +
               " m outside the plane of face " + std::to_string(f),
           static_cast<int>(f), static_cast<int>(v));
    }
    offset = std::max(offset, h);
  };
  if (use_hull) {
    // The highest vertex of all is a hull vertex; the face's own vertices count too (one may
    // be off the hull by round-off yet highest by it).
    check_vertex(static_cast<std::size_t>(highest_vertex(hull, shape.vertices, n, face[0])));
    for (int v : face) check_vertex(static_cast<std::size_t>(v));
  } else {
    for (std::size_t v = 0; v < shape.vertices.size(); ++v) check_vertex(v);
  }
  check_face_polygon(shape, f, n, own, tolerance);
  shape.face_normals.push_back(n);
  shape.face_offsets.push_back(offset);
}

/// Each vertex's neighbours in edge order (i gets j, j gets i), filled into the flat lists in two
/// passes: the degrees, then the entries.
void set_vertex_neighbours(ConvexPolyhedron& shape) {
  std::vector<std::uint32_t> degree(shape.vertices.size() + 1, 0);
  for (const auto& [i, j] : shape.edges) {
    ++degree[static_cast<std::size_t>(i) + 1];
    ++degree[static_cast<std::size_t>(j) + 1];
  }
  for (std::size_t v = 1; v < degree.size(); ++v) degree[v] += degree[v - 1];
  shape.vertex_neighbours.offsets = degree;
  shape.vertex_neighbours.indices.assign(degree.back(), -1);
  for (const auto& [i, j] : shape.edges) {
    shape.vertex_neighbours.indices[degree[static_cast<std::size_t>(i)]++] = j;
    shape.vertex_neighbours.indices[degree[static_cast<std::size_t>(j)]++] = i;
  }
}

}  // namespace

PolyhedronMassProperties polyhedron_mass_properties(const std::vector<Vec3>& vertices,
                                                    const std::vector<std::vector<int>>& faces) {
  return mass_properties(vertices, faces);
}

PolyhedronMassProperties polyhedron_mass_properties(const std::vector<Vec3>& vertices, const IndexLists& faces) {
  return mass_properties(vertices, faces);
}

ConvexPolyhedron make_convex_polyhedron(std::vector<Vec3> vertices, std::vector<std::vector<int>> faces,
                                        const PolyhedronBuildOptions& options, PolyhedronPose* pose) {
  // The mesh: counts and indices, then the topology (every directed edge once, its reverse once).
  check_counts(vertices, faces);
  MeshEdges mesh = paired_edges(sorted_directed_edges(vertices.size(), faces), vertices.size(), faces.size());
  // The mass properties and the body frame.
  const BodyFrameMass mass = move_to_body_frame(vertices, faces, options, pose);

  ConvexPolyhedron shape;
  shape.vertices = std::move(vertices);
  shape.faces = IndexLists(faces);
  faces = {};  // the nested copy is no longer needed
  shape.edges = std::move(mesh.edges);
  shape.edge_faces = std::move(mesh.edge_faces);
  shape.volume = mass.volume;
  shape.principal_inertia_per_density = mass.principal_inertia_per_density;
  set_bounds(shape);
  const double tolerance = options.convexity_tolerance * 2.0 * shape.bounding_radius;

  // Faces: normals, convexity, supporting planes. Every vertex must lie below every face's plane.
  // Large meshes find each face's highest vertex on the convex hull instead of scanning all
  // vertices (O(V log V) instead of O(F V): 10^5 vertices: 61 s of CPU, now 2.4 s,
  // bench/RESULTS.md); the check and the offsets are the same.
  const bool use_hull = shape.vertices.size() >= hull_check_min_vertices;
  const HullGraph hull = use_hull ? hull_graph(shape.vertices) : HullGraph{};
  shape.face_normals.reserve(shape.faces.size());
  shape.face_offsets.reserve(shape.faces.size());
  for (std::size_t f = 0; f < shape.faces.size(); ++f) add_face_plane(shape, f, hull, use_hull, tolerance);
  set_vertex_neighbours(shape);
  shrink_to_fit(shape);
  return shape;
}

void shrink_to_fit(ConvexPolyhedron& shape) {
  shape.vertices.shrink_to_fit();
  shape.faces.shrink_to_fit();
  shape.face_normals.shrink_to_fit();
  shape.edges.shrink_to_fit();
  shape.face_offsets.shrink_to_fit();
  shape.edge_faces.shrink_to_fit();
  shape.vertex_neighbours.shrink_to_fit();
}

ConvexPolyhedron scaled_polyhedron(const ConvexPolyhedron& shape, double factor) {
  if (!(factor > 0.0) || !std::isfinite(factor)) fail("scale factor must be positive, got " + std::to_string(factor));
  ConvexPolyhedron out = shape;
  for (Vec3& v : out.vertices) v *= factor;
  for (double& d : out.face_offsets) d *= factor;
  out.box_min *= factor;
  out.box_max *= factor;
  out.bounding_radius *= factor;
  out.volume *= factor * factor * factor;
  out.principal_inertia_per_density *= std::pow(factor, 5);
  return out;
}

ConvexPolyhedron make_box_polyhedron(const Vec3& half_extents) {
  const Vec3& h = half_extents;
  std::vector<Vec3> v;
  v.reserve(8);
  for (int k = 0; k < 8; ++k) {
    v.emplace_back((k & 1) ? h.x() : -h.x(), (k & 2) ? h.y() : -h.y(), (k & 4) ? h.z() : -h.z());
  }
  // CCW seen from outside.
  std::vector<std::vector<int>> f = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                     {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  return make_convex_polyhedron(std::move(v), std::move(f));
}

int support_vertex(const ConvexPolyhedron& shape, const Vec3& direction) {
  int best = 0;
  double best_value = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < shape.vertices.size(); ++i) {
    const double h = direction.dot(shape.vertices[i]);
    if (h > best_value) {
      best_value = h;
      best = static_cast<int>(i);
    }
  }
  return best;
}

double support_value(const ConvexPolyhedron& shape, const Vec3& direction) {
  double best = -std::numeric_limits<double>::infinity();
  for (const Vec3& v : shape.vertices) best = std::max(best, direction.dot(v));
  return best;
}

int add_polyhedron_grain(Model& model, ConvexPolyhedron shape, int material) {
  const double volume = shape.volume;
  const Vec3 inertia = shape.principal_inertia_per_density;
  return add_polyhedron(model, std::move(shape), volume, inertia, material);
}

}  // namespace rubble
