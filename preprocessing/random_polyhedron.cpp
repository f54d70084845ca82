#include "preprocessing/random_polyhedron.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Min_sphere_of_points_d_traits_3.h>
#include <CGAL/Min_sphere_of_spheres_d.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/convex_hull_3.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

#include "core/polyhedron.hpp"

namespace rubble {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;

/// Uniform double in [0, 1) from the top 53 bits of one 64-bit draw.
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// Uniform integer in [lo, hi] (rejection sampling: no modulo bias).
int uniform_int(std::mt19937_64& rng, int lo, int hi) {
  const std::uint64_t range = static_cast<std::uint64_t>(hi - lo) + 1;
  const std::uint64_t limit =
      std::numeric_limits<std::uint64_t>::max() - std::numeric_limits<std::uint64_t>::max() % range;
  std::uint64_t x;
  do {
    x = rng();
  } while (x >= limit);
  return lo + static_cast<int>(x % range);
}

Mesh hull_mesh(const std::vector<Vec3>& points) {
  std::vector<Point> cgal_points;
  cgal_points.reserve(points.size());
  for (const Vec3& p : points) cgal_points.emplace_back(p.x(), p.y(), p.z());
  Mesh mesh;
  if (points.size() >= 4) CGAL::convex_hull_3(cgal_points.begin(), cgal_points.end(), mesh);
  if (mesh.number_of_faces() < 4 || !CGAL::is_closed(mesh)) {
    throw std::runtime_error("convex hull of " + std::to_string(points.size()) +
                             " points is degenerate (the points are coincident, collinear or coplanar)");
  }
  return mesh;
}

Vec3 newell(const std::vector<Vec3>& v, const std::vector<int>& face) {
  Vec3 n = Vec3::Zero();
  for (std::size_t i = 0; i < face.size(); ++i) {
    n += v[static_cast<std::size_t>(face[i])].cross(v[static_cast<std::size_t>(face[(i + 1) % face.size()])]);
  }
  return n;
}

void check_options(const RandomPolyhedronOptions& o) {
  auto bad = [](const std::string& what) { throw std::invalid_argument("random polyhedron: " + what); };
  if (o.min_vertices < 4) bad("min_vertices = " + std::to_string(o.min_vertices) + ", expected >= 4");
  if (o.max_vertices < o.min_vertices) {
    bad("max_vertices = " + std::to_string(o.max_vertices) +
        ", expected >= min_vertices = " + std::to_string(o.min_vertices));
  }
  if (o.max_vertices > 100000) bad("max_vertices = " + std::to_string(o.max_vertices) + ", expected <= 100000");
  if (!(o.min_elongation > 0.0 && o.min_elongation <= 1.0))
    bad("min_elongation = " + std::to_string(o.min_elongation) + ", expected in (0, 1]");
  if (!(o.min_platyness > 0.0 && o.min_platyness <= 1.0))
    bad("min_platyness = " + std::to_string(o.min_platyness) + ", expected in (0, 1]");
  if (!(o.diameter > 0.0) || !std::isfinite(o.diameter))
    bad("diameter = " + std::to_string(o.diameter) + ", expected > 0");
  if (!(o.merge_angle_degrees >= 0.0 && o.merge_angle_degrees < 30.0)) {
    bad("merge_angle_degrees = " + std::to_string(o.merge_angle_degrees) + ", expected in [0, 30)");
  }
}

/// The faces' unit normals and areas (Newell's method), and the face of each directed edge.
struct FaceAdjacency {
  std::vector<Vec3> normals;
  std::vector<double> areas;
  std::map<std::pair<int, int>, int> face_of_edge;  ///< directed edge -> face
};

FaceAdjacency face_adjacency(const std::vector<Vec3>& vertices, const std::vector<std::vector<int>>& faces) {
  const std::size_t nf = faces.size();
  FaceAdjacency out;
  out.normals.resize(nf);
  out.areas.resize(nf);
  for (std::size_t f = 0; f < nf; ++f) {
    const Vec3 n = newell(vertices, faces[f]);
    out.areas[f] = 0.5 * n.norm();
    out.normals[f] = n.normalized();
    for (std::size_t i = 0; i < faces[f].size(); ++i) {
      out.face_of_edge[{faces[f][i], faces[f][(i + 1) % faces[f].size()]}] = static_cast<int>(f);
    }
  }
  return out;
}

/// Region growing from face `seed` into group g: neighbours (across an edge) still in no group
/// whose normal is within the angle of the seed's (not of the neighbour's, so a slowly curving
/// surface does not collapse into one face). Returns the members, seed first.
std::vector<int> grow_region(std::size_t seed, int g, const std::vector<std::vector<int>>& faces,
                             const FaceAdjacency& adjacency, double cos_angle, std::vector<int>& group) {
  const Vec3 seed_normal = adjacency.normals[seed];
  std::vector<int> members{static_cast<int>(seed)};
  group[seed] = g;
  for (std::size_t k = 0; k < members.size(); ++k) {
    const auto& face = faces[static_cast<std::size_t>(members[k])];
    for (std::size_t i = 0; i < face.size(); ++i) {
      const auto it = adjacency.face_of_edge.find({face[(i + 1) % face.size()], face[i]});
      if (it == adjacency.face_of_edge.end()) continue;
      const auto neighbour = static_cast<std::size_t>(it->second);
      if (group[neighbour] == -1 && adjacency.normals[neighbour].dot(seed_normal) >= cos_angle) {
        group[neighbour] = g;
        members.push_back(static_cast<int>(neighbour));
      }
    }
  }
  return members;
}

/// The boundary of group g (the directed edges of its members whose twin belongs to another
/// group) as one loop of vertices; empty when it is not a single simple loop (pinched, or
/// several loops).
std::vector<int> boundary_loop(const std::vector<int>& members, int g, const std::vector<std::vector<int>>& faces,
                               const FaceAdjacency& adjacency, const std::vector<int>& group) {
  std::map<int, int> next;
  std::size_t boundary_edges = 0;
  for (int m : members) {
    const auto& face = faces[static_cast<std::size_t>(m)];
    for (std::size_t i = 0; i < face.size(); ++i) {
      const int from = face[i];
      const int to = face[(i + 1) % face.size()];
      const auto twin = adjacency.face_of_edge.find({to, from});
      if (twin != adjacency.face_of_edge.end() && group[static_cast<std::size_t>(twin->second)] == g) continue;
      ++boundary_edges;
      if (!next.emplace(from, to).second) return {};  // pinched boundary
    }
  }
  std::vector<int> loop;
  if (next.empty()) return loop;
  int v = next.begin()->first;
  do {
    loop.push_back(v);
    const auto it = next.find(v);
    if (it == next.end() || loop.size() > boundary_edges) return {};
    v = it->second;
  } while (v != loop.front());
  if (loop.size() != boundary_edges) return {};
  return loop;
}

/// True when the polygon `loop` turns left at every corner seen along `normal` (convex), to
/// 1e-12 scale^2.
bool is_convex_polygon(const std::vector<Vec3>& vertices, const std::vector<int>& loop, const Vec3& normal,
                       double scale) {
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const Vec3& p = vertices[static_cast<std::size_t>(loop[i])];
    const Vec3& q = vertices[static_cast<std::size_t>(loop[(i + 1) % loop.size()])];
    const Vec3& r = vertices[static_cast<std::size_t>(loop[(i + 2) % loop.size()])];
    if (normal.dot((q - p).cross(r - q)) < -1e-12 * scale * scale) return false;
  }
  return true;
}

/// The vertices used by `faces` and by none of `merged`, in increasing order.
std::vector<int> vertices_left_inside(std::size_t vertex_count, const std::vector<std::vector<int>>& faces,
                                      const std::vector<std::vector<int>>& merged) {
  std::vector<char> on_output(vertex_count, 0);
  std::vector<char> on_input(vertex_count, 0);
  for (const auto& face : faces) {
    for (int v : face) on_input[static_cast<std::size_t>(v)] = 1;
  }
  for (const auto& face : merged) {
    for (int v : face) on_output[static_cast<std::size_t>(v)] = 1;
  }
  std::vector<int> inside;
  for (std::size_t v = 0; v < vertex_count; ++v) {
    if (on_input[v] && !on_output[v]) inside.push_back(static_cast<int>(v));
  }
  return inside;
}

}  // namespace

std::vector<std::array<int, 3>> convex_hull_triangles(const std::vector<Vec3>& points) {
  const Mesh mesh = hull_mesh(points);
  // Hull vertices are copies of input points: find their indices by exact coordinates.
  std::map<std::array<double, 3>, int> index;
  for (std::size_t i = 0; i < points.size(); ++i)
    index.emplace(std::array<double, 3>{points[i].x(), points[i].y(), points[i].z()}, static_cast<int>(i));
  std::vector<std::array<int, 3>> triangles;
  for (const auto face : mesh.faces()) {
    std::array<int, 3> t{};
    int k = 0;
    for (const auto v : CGAL::vertices_around_face(mesh.halfedge(face), mesh)) {
      const Point& p = mesh.point(v);
      if (k < 3) t[static_cast<std::size_t>(k)] = index.at({p.x(), p.y(), p.z()});
      ++k;
    }
    if (k != 3) throw std::runtime_error("convex hull: a facet is not a triangle");
    // Canonical order (smallest index first, triangles sorted), so the result does not depend
    // on the order CGAL reports the facets in.
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    triangles.push_back(t);
  }
  std::sort(triangles.begin(), triangles.end());
  return triangles;
}

Ball smallest_enclosing_ball(const std::vector<Vec3>& points) {
  if (points.empty()) throw std::invalid_argument("smallest_enclosing_ball: no point");
  // With double as the number type CGAL runs its floating-point algorithm (Selector<double>:
  // Result = double), so the centre and radius are plain doubles.
  using Traits = CGAL::Min_sphere_of_points_d_traits_3<Kernel, double>;
  std::vector<Point> cgal_points;
  cgal_points.reserve(points.size());
  for (const Vec3& p : points) cgal_points.emplace_back(p.x(), p.y(), p.z());
  CGAL::Min_sphere_of_spheres_d<Traits> min_sphere(cgal_points.begin(),
                                                   cgal_points.end());  // radius() updates lazily: not const
  Ball ball;
  ball.radius = CGAL::to_double(min_sphere.radius());
  auto coordinate = min_sphere.center_cartesian_begin();
  for (int k = 0; k < 3; ++k, ++coordinate) ball.centre[k] = CGAL::to_double(*coordinate);
  return ball;
}

double convex_hull_volume(const std::vector<Vec3>& points) {
  return CGAL::to_double(CGAL::Polygon_mesh_processing::volume(hull_mesh(points)));
}

std::vector<std::vector<int>> merge_coplanar_faces(const std::vector<Vec3>& vertices,
                                                   const std::vector<std::vector<int>>& faces, double angle_degrees,
                                                   std::vector<int>& interior_vertices) {
  interior_vertices.clear();
  if (angle_degrees <= 0.0) return faces;
  const double cos_angle = std::cos(angle_degrees * std::numbers::pi / 180.0);
  const std::size_t nf = faces.size();
  double scale = 0.0;
  for (const Vec3& v : vertices) scale = std::max(scale, v.norm());
  const FaceAdjacency adjacency = face_adjacency(vertices, faces);
  // Largest faces first: they seed the groups.
  std::vector<std::size_t> order(nf);
  for (std::size_t f = 0; f < nf; ++f) order[f] = f;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t x, std::size_t y) { return adjacency.areas[x] > adjacency.areas[y]; });

  std::vector<int> group(nf, -1);
  std::vector<std::vector<int>> result;
  int groups = 0;
  for (std::size_t seed : order) {
    if (group[seed] != -1) continue;
    const int g = groups++;
    const std::vector<int> members = grow_region(seed, g, faces, adjacency, cos_angle, group);
    // A group of several faces becomes one face when its boundary is a single loop and a convex
    // polygon seen along the seed's normal; otherwise its faces stay as they are.
    const std::vector<int> loop =
        members.size() == 1 ? std::vector<int>{} : boundary_loop(members, g, faces, adjacency, group);
    if (loop.size() >= 3 && is_convex_polygon(vertices, loop, adjacency.normals[seed], scale)) {
      result.push_back(loop);
    } else {
      for (int m : members) result.push_back(faces[static_cast<std::size_t>(m)]);
    }
  }
  interior_vertices = vertices_left_inside(vertices.size(), faces, result);
  return result;
}

ConvexPolyhedron generate_random_polyhedron(const RandomPolyhedronOptions& options, std::uint64_t seed) {
  check_options(options);
  std::mt19937_64 rng(seed);
  const int vertex_count = uniform_int(rng, options.min_vertices, options.max_vertices);
  const double elongation = options.min_elongation + (1.0 - options.min_elongation) * uniform01(rng);
  const double platyness = options.min_platyness + (1.0 - options.min_platyness) * uniform01(rng);
  const Vec3 axes(1.0, elongation, elongation * platyness);
  std::vector<Vec3> points;
  points.reserve(static_cast<std::size_t>(vertex_count));
  for (int i = 0; i < vertex_count; ++i) {
    // Uniform on the sphere (Archimedes): z uniform in [-1, 1], longitude uniform.
    const double z = 2.0 * uniform01(rng) - 1.0;
    const double phi = 2.0 * std::numbers::pi * uniform01(rng);
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    points.push_back(Vec3(r * std::cos(phi), r * std::sin(phi), z).cwiseProduct(axes));
  }

  // Hull, merge, and drop the vertices a merge left inside a face; the hull of the remaining
  // points is recomputed until no merge swallows a vertex (a few rounds at most).
  std::vector<std::vector<int>> faces;
  std::vector<std::vector<int>> triangles;  // CGAL's, for exact mass properties
  for (int round = 0;; ++round) {
    triangles.clear();
    for (const auto& t : convex_hull_triangles(points)) triangles.push_back({t[0], t[1], t[2]});
    std::vector<int> interior;
    faces = merge_coplanar_faces(points, triangles, options.merge_angle_degrees, interior);
    if (interior.empty() || round == 20) break;
    std::vector<char> drop(points.size(), 0);
    for (int v : interior) drop[static_cast<std::size_t>(v)] = 1;
    std::vector<Vec3> kept;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!drop[i]) kept.push_back(points[i]);
    }
    if (kept.size() < 4) throw std::runtime_error("random polyhedron: merging faces left fewer than 4 vertices");
    points = std::move(kept);
  }
  // Keep only the vertices on a face, renumbered.
  std::vector<int> renumber(points.size(), -1);
  std::vector<Vec3> vertices;
  for (auto& face : faces) {
    for (int& v : face) {
      if (renumber[static_cast<std::size_t>(v)] < 0) {
        renumber[static_cast<std::size_t>(v)] = static_cast<int>(vertices.size());
        vertices.push_back(points[static_cast<std::size_t>(v)]);
      }
      v = renumber[static_cast<std::size_t>(v)];
    }
  }
  PolyhedronBuildOptions build;
  // Mass properties from the hull's triangles: exact even where a merged face is bent.
  bool complete = true;
  for (auto& t : triangles) {
    for (int& v : t) {
      complete = complete && renumber[static_cast<std::size_t>(v)] >= 0;
      v = complete ? renumber[static_cast<std::size_t>(v)] : 0;
    }
  }
  if (complete) build.mass_faces = std::move(triangles);
  // A merged face may bend by up to the merge angle over its width.
  build.convexity_tolerance = 1e-9 + 2.0 * std::sin(options.merge_angle_degrees * std::numbers::pi / 180.0);
  ConvexPolyhedron shape;
  try {
    shape = make_convex_polyhedron(std::move(vertices), std::move(faces), build);
  } catch (const PolyhedronError& e) {
    throw std::runtime_error(std::string("random polyhedron (seed ") + std::to_string(seed) + "): " + e.what());
  }

  // Circumscribed sphere: the smallest sphere enclosing the vertices.
  const double radius = smallest_enclosing_ball(shape.vertices).radius;
  return scaled_polyhedron(shape, options.diameter / (2.0 * radius));
}

}  // namespace rubble
