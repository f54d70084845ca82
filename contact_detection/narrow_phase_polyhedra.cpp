#include "contact_detection/narrow_phase_polyhedra.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "contact_detection/common_plane.hpp"
#include "contact_detection/contact_polygon.hpp"
#include "core/polyhedron.hpp"

namespace rubble {
namespace {

using namespace contact_polygon;

PolyhedronInWorld placed(const Model& model, const State& state, std::uint32_t body) {
  return {&model.polyhedra[static_cast<std::size_t>(model.shape_index[body])], state.position[body],
          state.orientation[body].toRotationMatrix()};
}

/// Appends a contact point.
void push_contact(std::uint32_t a, std::uint32_t b, std::uint32_t feature_a, std::uint32_t feature_b,
                  const Vec3& normal, const Vec3& point, double gap, ContactList& contacts) {
  Contact c;
  c.id = ContactId{a, b, feature_a, feature_b};
  c.point = point;
  c.frame = frame_from_normal(normal);
  c.gap = gap;
  contacts.push_back(c);
}

/// Two polyhedra seen from A's frame, with the common plane's frame (n from A to B, tangents t
/// and s): what each stage of contacts_on_common_plane reads.
struct PairOnPlane {
  const ConvexPolyhedron* A = nullptr;
  const ConvexPolyhedron* B = nullptr;
  Mat3 rotation;                  ///< B's frame -> A's frame
  Vec3 translation;               ///< m, B's origin in A's frame
  double size = 0.0;              ///< m, the smaller bounding radius
  Vec3 n, t, s;                   ///< the plane's normal and tangents in A's frame
  std::vector<Vec3> vb;           ///< m, B's vertices in A's frame
  double top_a = 0.0;             ///< m, A's extreme height along n
  double bottom_b = 0.0;          ///< m, B's extreme height along -n
  double linear_tolerance = 0.0;  ///< m, 1e-7 of the size: round-off of the caps' hulls
  /// m, features closer than this in the plane count as coincident, and a vertex this close outside
  /// the other polygon still counts as inside: stacked, aligned faces then keep the same contact
  /// ids (hence warm starts) while they creep by less than 1e-3 of the grain size.
  double feature_tolerance = 0.0;
  /// B's faces turned against n, as (m.t, m.s, m.n, offset) in A's frame.
  std::vector<std::array<double, 4>> faces_down;
  int face_a = 0;  ///< A's face most turned towards n: the "face" side of vertex-face points
  int face_b = 0;  ///< B's face most turned against n
};

PairOnPlane place_on_plane(const PolyhedronInWorld& pa, const PolyhedronInWorld& pb, const Vec3& normal_world) {
  PairOnPlane q;
  q.A = pa.shape;
  q.B = pb.shape;
  const ConvexPolyhedron& A = *pa.shape;
  const ConvexPolyhedron& B = *pb.shape;
  q.rotation = pa.rotation.transpose() * pb.rotation;
  q.translation = pa.rotation.transpose() * (pb.position - pa.position);
  q.size = std::min(A.bounding_radius, B.bounding_radius);
  q.n = pa.rotation.transpose() * normal_world;
  const Mat3 plane = frame_from_normal(q.n);
  q.t = plane.col(1);
  q.s = plane.col(2);
  q.vb.resize(B.vertices.size());
  for (std::size_t i = 0; i < q.vb.size(); ++i) q.vb[i] = q.rotation * B.vertices[i] + q.translation;
  q.top_a = -std::numeric_limits<double>::infinity();
  for (const Vec3& v : A.vertices) q.top_a = std::max(q.top_a, q.n.dot(v));
  q.bottom_b = std::numeric_limits<double>::infinity();
  for (const Vec3& v : q.vb) q.bottom_b = std::min(q.bottom_b, q.n.dot(v));
  q.linear_tolerance = 1e-7 * q.size;
  q.feature_tolerance = 1e-3 * q.size;
  for (std::size_t f = 0; f < B.face_normals.size(); ++f) {
    const Vec3 m = q.rotation * B.face_normals[f];
    const double down = m.dot(q.n);
    if (down >= -1e-6) continue;
    q.faces_down.push_back({m.dot(q.t), m.dot(q.s), down, B.face_offsets[f] + m.dot(q.translation)});
  }
  double best_up = -2.0;
  for (std::size_t f = 0; f < A.face_normals.size(); ++f) {
    if (A.face_normals[f].dot(q.n) > best_up) {
      best_up = A.face_normals[f].dot(q.n);
      q.face_a = static_cast<int>(f);
    }
  }
  double best_down = 2.0;
  for (std::size_t f = 0; f < B.face_normals.size(); ++f) {
    const double d = (q.rotation * B.face_normals[f]).dot(q.n);
    if (d < best_down) {
      best_down = d;
      q.face_b = static_cast<int>(f);
    }
  }
  return q;
}

/// A's upper surface above the plane point p: the lower envelope of its faces turned towards n.
double height_a(const PairOnPlane& q, const Vec2& p) {
  double z = std::numeric_limits<double>::infinity();
  for (std::size_t f = 0; f < q.A->face_normals.size(); ++f) {
    const Vec3& m = q.A->face_normals[f];
    const double up = m.dot(q.n);
    if (up <= 1e-6) continue;
    z = std::min(z, (q.A->face_offsets[f] - p.x() * m.dot(q.t) - p.y() * m.dot(q.s)) / up);
  }
  return z;
}

/// B's lower surface below the plane point p: the upper envelope of its faces turned against n.
double height_b(const PairOnPlane& q, const Vec2& p) {
  double z = -std::numeric_limits<double>::infinity();
  for (const auto& m : q.faces_down) z = std::max(z, (m[3] - p.x() * m[0] - p.y() * m[1]) / m[2]);
  return z;
}

/// The caps of A and B: their vertices within `depth` of the body's extreme along n, projected
/// on the plane, as convex hulls.
std::pair<Polygon, Polygon> caps(const PairOnPlane& q, double depth) {
  Polygon cap_a, cap_b;
  for (std::size_t i = 0; i < q.A->vertices.size(); ++i) {
    const Vec3& v = q.A->vertices[i];
    if (q.n.dot(v) >= q.top_a - depth) cap_a.push_back({Vec2(q.t.dot(v), q.s.dot(v)), static_cast<int>(i)});
  }
  for (std::size_t i = 0; i < q.vb.size(); ++i) {
    const Vec3& v = q.vb[i];
    if (q.n.dot(v) <= q.bottom_b + depth) cap_b.push_back({Vec2(q.t.dot(v), q.s.dot(v)), static_cast<int>(i)});
  }
  return {hull_2d(std::move(cap_a), q.linear_tolerance), hull_2d(std::move(cap_b), q.linear_tolerance)};
}

/// Adds the candidate at plane point p (surface heights za of A, zb of B) unless one lies within
/// the feature tolerance already (coincident features).
void add_candidate(const PairOnPlane& q, const Vec2& p, double za, double zb, std::uint32_t feature_a,
                   std::uint32_t feature_b, std::vector<Candidate>& candidates) {
  for (const Candidate& c : candidates) {
    if ((c.p - p).norm() <= q.feature_tolerance) return;
  }
  candidates.push_back({p, zb - za, za, zb, feature_a, feature_b});
}

/// The points of the intersection of two cap polygons: the vertices of each inside the other,
/// then the crossings of their edges.
void add_polygon_intersection(const PairOnPlane& q, const Polygon& polygon_a, const Polygon& polygon_b,
                              std::vector<Candidate>& candidates) {
  for (const CapVertex& c : polygon_a) {
    if (inside(polygon_b, c.p, q.feature_tolerance)) {
      add_candidate(q, c.p, q.n.dot(q.A->vertices[static_cast<std::size_t>(c.vertex)]),
                    height_b(q, clamp_into(polygon_b, c.p)), vertex_code(c.vertex), face_code(q.face_b), candidates);
    }
  }
  for (const CapVertex& c : polygon_b) {
    if (inside(polygon_a, c.p, q.feature_tolerance)) {
      add_candidate(q, c.p, height_a(q, clamp_into(polygon_a, c.p)), q.n.dot(q.vb[static_cast<std::size_t>(c.vertex)]),
                    face_code(q.face_a), vertex_code(c.vertex), candidates);
    }
  }
  const std::size_t edges_a = polygon_a.size() < 2 ? 0 : (polygon_a.size() == 2 ? 1 : polygon_a.size());
  const std::size_t edges_b = polygon_b.size() < 2 ? 0 : (polygon_b.size() == 2 ? 1 : polygon_b.size());
  for (std::size_t i = 0; i < edges_a; ++i) {
    const CapVertex& a0 = polygon_a[i];
    const CapVertex& a1 = polygon_a[(i + 1) % polygon_a.size()];
    for (std::size_t j = 0; j < edges_b; ++j) {
      const CapVertex& b0 = polygon_b[j];
      const CapVertex& b1 = polygon_b[(j + 1) % polygon_b.size()];
      Vec2 at;
      if (!segments_cross(a0.p, a1.p, b0.p, b1.p, at)) continue;
      // The cap hull's edges may be chords across a curved cap: take the surfaces' heights
      // there (exact on a true edge, and above a chord).
      const double za = height_a(q, at);
      const double zb = height_b(q, at);
      add_candidate(q, at, za, zb, edge_code(a0.vertex, a1.vertex, q.A->vertices.size()),
                    edge_code(b0.vertex, b1.vertex, q.B->vertices.size()), candidates);
    }
  }
}

/// When the supports' projections do not meet (round-off, or a merged face bending the Gauss
/// map): one point between their closest features, carrying the plane's gap, so the overlap
/// measured by the common plane is always represented.
void add_closest_features_point(const PairOnPlane& q, const Polygon& polygon_a, const Polygon& polygon_b,
                                std::vector<Candidate>& candidates) {
  double best = std::numeric_limits<double>::infinity();
  Vec2 point_a = polygon_a[0].p, point_b = polygon_b[0].p;
  std::uint32_t feature_a = vertex_code(polygon_a[0].vertex), feature_b = vertex_code(polygon_b[0].vertex);
  for (const CapVertex& x : polygon_a) {
    std::uint32_t f = 0;
    const Vec2 c = closest_on_boundary(polygon_b, x.p, q.B->vertices.size(), f);
    if ((c - x.p).squaredNorm() < best) {
      best = (c - x.p).squaredNorm();
      point_a = x.p;
      point_b = c;
      feature_a = vertex_code(x.vertex);
      feature_b = f;
    }
  }
  for (const CapVertex& y : polygon_b) {
    std::uint32_t f = 0;
    const Vec2 c = closest_on_boundary(polygon_a, y.p, q.A->vertices.size(), f);
    if ((c - y.p).squaredNorm() < best) {
      best = (c - y.p).squaredNorm();
      point_a = c;
      point_b = y.p;
      feature_a = f;
      feature_b = vertex_code(y.vertex);
    }
  }
  add_candidate(q, 0.5 * (point_a + point_b), q.top_a, q.bottom_b, feature_a, feature_b, candidates);
}

/// Ridges inside the caps: where an edge of one body crosses a curved cap of the other, the gap
/// along it has its kinks (and the overlap its corners) at the cap's interior edges, which the
/// caps' hulls do not see; missing them lets a sliding edge sink into the next facet in one step.
/// Adds the crossings of the edges of A and B within `depth` of their extremes.
void add_ridge_crossings(const PairOnPlane& q, double depth, std::vector<Candidate>& candidates) {
  struct Segment {
    CapVertex from, to;
  };
  std::vector<Segment> ridges_a, ridges_b;
  for (const auto& [i, j] : q.A->edges) {
    const Vec3& x = q.A->vertices[static_cast<std::size_t>(i)];
    const Vec3& y = q.A->vertices[static_cast<std::size_t>(j)];
    if (q.n.dot(x) < q.top_a - depth || q.n.dot(y) < q.top_a - depth) continue;
    ridges_a.push_back({{Vec2(q.t.dot(x), q.s.dot(x)), i}, {Vec2(q.t.dot(y), q.s.dot(y)), j}});
  }
  for (const auto& [i, j] : q.B->edges) {
    const Vec3& x = q.vb[static_cast<std::size_t>(i)];
    const Vec3& y = q.vb[static_cast<std::size_t>(j)];
    if (q.n.dot(x) > q.bottom_b + depth || q.n.dot(y) > q.bottom_b + depth) continue;
    ridges_b.push_back({{Vec2(q.t.dot(x), q.s.dot(x)), i}, {Vec2(q.t.dot(y), q.s.dot(y)), j}});
  }
  for (const Segment& ea : ridges_a) {
    for (const Segment& eb : ridges_b) {
      Vec2 at;
      if (!segments_cross(ea.from.p, ea.to.p, eb.from.p, eb.to.p, at)) continue;
      add_candidate(q, at, height_a(q, at), height_b(q, at),
                    edge_code(ea.from.vertex, ea.to.vertex, q.A->vertices.size()),
                    edge_code(eb.from.vertex, eb.to.vertex, q.B->vertices.size()), candidates);
    }
  }
}

/// Contact points of two polyhedra on their common plane (normal from A to B, separation `gap`):
/// the caps of A and B (vertices within the depth that can still give a local gap below the
/// alert distance) are projected on the plane, their convex polygons intersected (vertices of
/// one inside the other, crossings of their edges), and each point of the intersection gets
/// its local gap from the two bodies' surfaces above and below it. Vertex-face gives 1 point,
/// edge-edge 1, edge-face 2, face-face the clipped polygon, reduced to <= 4 points.
void contacts_on_common_plane(const PolyhedronInWorld& pa, const PolyhedronInWorld& pb, std::uint32_t body_a,
                              std::uint32_t body_b, const Vec3& normal_world, double gap, double alert_distance,
                              ContactList& contacts) {
  const PairOnPlane q = place_on_plane(pa, pb, normal_world);
  // Two sets of caps: the support features (depth ~ 0), whose overlap holds the deepest point
  // (at the optimal plane the supports' projections meet), and the alert caps, which add the
  // points of a nearly flush face that may close within the alert distance: a local gap below
  // the alert distance needs depth_a + depth_b < alert - gap. Alert caps are measured as if the
  // bodies touched (gap clamped at 0), so a deep overlap does not turn them into curved patches
  // whose hull hides their lowest vertices.
  const double alert_depth = std::max(alert_distance - std::max(gap, 0.0), 0.0) + q.linear_tolerance;
  const auto support_polygons = caps(q, q.linear_tolerance);
  const auto alert_polygons = caps(q, alert_depth);
  std::vector<Candidate> candidates;
  add_polygon_intersection(q, support_polygons.first, support_polygons.second, candidates);
  if (candidates.empty()) add_closest_features_point(q, support_polygons.first, support_polygons.second, candidates);
  add_polygon_intersection(q, alert_polygons.first, alert_polygons.second, candidates);
  add_ridge_crossings(q, alert_depth, candidates);

  std::vector<Candidate> active;
  for (const Candidate& c : candidates) {
    if (c.gap < alert_distance) active.push_back(c);
  }
  const std::vector<Candidate> kept =
      add_off_plane_points(active, reduce_to_four(active, 1e-12 * q.size * q.size),
                           std::max(q.linear_tolerance, 0.01 * alert_distance), max_points_per_pair);
  for (const Candidate& c : kept) {
    const Vec3 local = c.p.x() * q.t + c.p.y() * q.s + 0.5 * (c.height_a + c.height_b) * q.n;
    push_contact(body_a, body_b, c.feature_a, c.feature_b, normal_world, pa.rotation * local + pa.position, c.gap,
                 contacts);
  }
}

}  // namespace

void collide_polyhedron_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                                   double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                                   Vec3& common_normal) {
  // Bounding spheres first: most broad-phase pairs stop here.
  const double centre_distance = (state.position[b] - state.position[a]).norm();
  if (centre_distance - model.bounding_radius[a] - model.bounding_radius[b] >= alert_distance) return;
  const PolyhedronInWorld pa = placed(model, state, a);
  const PolyhedronInWorld pb = placed(model, state, b);
  const CommonPlane plane = find_common_plane(pa, pb, previous_common_normal, alert_distance);
  common_normal = plane.normal;
  if (!plane.complete || plane.gap >= alert_distance) return;
  contacts_on_common_plane(pa, pb, a, b, plane.normal, plane.gap, alert_distance, contacts);
}

void collide_box_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                            double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                            Vec3& common_normal) {
  // A box wall is a convex polyhedron with 8 vertices: the same common-plane method applies.
  const ConvexPolyhedron box =
      make_box_polyhedron(model.boxes[static_cast<std::size_t>(model.shape_index[wall])].half_extents);
  const PolyhedronInWorld pa{&box, state.position[wall], state.orientation[wall].toRotationMatrix()};
  const PolyhedronInWorld pb = placed(model, state, grain);
  // The warm-start memory is keyed by the ordered pair; the dispatcher passes (wall, grain) and
  // stores the normal as returned here (from the wall to the grain).
  const CommonPlane plane = find_common_plane(pa, pb, previous_common_normal, alert_distance);
  common_normal = plane.normal;
  if (!plane.complete || plane.gap >= alert_distance) return;
  contacts_on_common_plane(pa, pb, wall, grain, plane.normal, plane.gap, alert_distance, contacts);
}

void collide_plane_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                              double alert_distance, ContactList& contacts) {
  const Plane& plane = model.planes[static_cast<std::size_t>(model.shape_index[wall])];
  const Vec3 normal = state.orientation[wall] * plane.normal;
  const double offset = normal.dot(state.position[wall]);
  const PolyhedronInWorld grain_pose = placed(model, state, grain);
  const ConvexPolyhedron& shape = *grain_pose.shape;
  // Quick exit: the whole bounding sphere is beyond the alert distance.
  if (normal.dot(state.position[grain]) - offset - shape.bounding_radius >= alert_distance) return;
  const Mat3 frame = frame_from_normal(normal);
  const Vec3 normal_body = grain_pose.rotation.transpose() * normal;
  const double centre_height = normal.dot(state.position[grain]) - offset;
  std::vector<Candidate> candidates;
  for (std::size_t i = 0; i < shape.vertices.size(); ++i) {
    const double gap = centre_height + normal_body.dot(shape.vertices[i]);
    if (gap >= alert_distance) continue;
    const Vec3 x = grain_pose.rotation * shape.vertices[i] + grain_pose.position;
    candidates.push_back(
        {Vec2(frame.col(1).dot(x), frame.col(2).dot(x)), gap, 0.0, 0.0, 0u, vertex_code(static_cast<int>(i))});
  }
  const double size = shape.bounding_radius;
  const double linear_tolerance = 1e-7 * size;
  const std::vector<Candidate> kept =
      add_off_plane_points(candidates, reduce_to_four(candidates, 1e-12 * size * size),
                           std::max(linear_tolerance, 0.01 * alert_distance), max_points_per_pair);
  for (const Candidate& c : kept) {
    const int vertex = static_cast<int>(c.feature_b & index_mask);
    const Vec3 x = grain_pose.rotation * shape.vertices[static_cast<std::size_t>(vertex)] + grain_pose.position;
    push_contact(wall, grain, 0u, c.feature_b, normal, x - 0.5 * c.gap * normal, c.gap, contacts);
  }
}

void collide_sphere_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                               double alert_distance, ContactList& contacts) {
  const bool sphere_first = model.shape_kind[a] == ShapeKind::sphere;
  const std::uint32_t sphere = sphere_first ? a : b;
  const std::uint32_t polyhedron = sphere_first ? b : a;
  const double radius = model.sphere_radius(sphere);
  const Vec3 centre_line = state.position[sphere] - state.position[polyhedron];
  if (centre_line.norm() - radius - model.bounding_radius[polyhedron] >= alert_distance) return;
  const PolyhedronInWorld pose = placed(model, state, polyhedron);
  const ConvexPolyhedron& shape = *pose.shape;
  const Vec3 centre = pose.rotation.transpose() * centre_line;  // sphere centre in the body frame

  // Deepest face plane: if the centre is behind every face it is inside, and the face it is
  // closest to gives the normal (exact signed distance for a point inside a convex polyhedron).
  double signed_distance = -std::numeric_limits<double>::infinity();
  int face = 0;
  for (std::size_t f = 0; f < shape.face_normals.size(); ++f) {
    const double d = shape.face_normals[f].dot(centre) - shape.face_offsets[f];
    if (d > signed_distance) {
      signed_distance = d;
      face = static_cast<int>(f);
    }
  }
  Vec3 normal_body = shape.face_normals[static_cast<std::size_t>(face)];
  Vec3 surface = centre - signed_distance * normal_body;
  double distance = signed_distance;
  if (signed_distance > 0.0) {
    Vec3 closest;
    if (closest_point_on_polyhedron(shape, centre, closest)) {
      const Vec3 offset = centre - closest;
      distance = offset.norm();
      if (distance > 0.0) normal_body = offset / distance;
      surface = closest;
    }
  }
  const double gap = distance - radius;
  if (gap >= alert_distance) return;
  const Vec3 normal = pose.rotation * normal_body;  // polyhedron -> sphere
  const Vec3 point = pose.rotation * surface + pose.position + 0.5 * gap * normal;
  push_contact(a, b, 0u, 0u, sphere_first ? Vec3(-normal) : normal, point, gap, contacts);
}

}  // namespace rubble
