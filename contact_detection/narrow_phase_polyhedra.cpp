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

/// Appends a contact point with the frame (n, t, s) of the common plane.
void push_contact(std::uint32_t a, std::uint32_t b, std::uint32_t feature_a, std::uint32_t feature_b, const Mat3& frame,
                  const Vec3& point, double gap, ContactList& contacts) {
  Contact c;
  c.id = ContactId{a, b, feature_a, feature_b};
  c.point = point;
  c.frame = frame;
  c.gap = gap;
  contacts.push_back(c);
}

/// Appends a contact point with normal `normal`.
void push_contact(std::uint32_t a, std::uint32_t b, std::uint32_t feature_a, std::uint32_t feature_b,
                  const Vec3& normal, const Vec3& point, double gap, ContactList& contacts) {
  push_contact(a, b, feature_a, feature_b, frame_from_normal(normal), point, gap, contacts);
}

/// The faces of A turned towards n (its upper surface) and of B turned against it (its lower
/// surface), and the face of each most turned so. Each face's n-component is computed once here
/// and read by the face selection and by every surface height.
void surfaces_on_plane(PairOnPlane& q) {
  const PolyhedronPair& pair = *q.pair;
  const ConvexPolyhedron& A = *pair.A;
  const ConvexPolyhedron& B = *pair.B;
  // Every face is written and the count advanced only for those turned the right way: about
  // half the faces are, in no order a branch predictor could learn.
  q.faces_up.resize(A.face_normals.size());
  std::size_t up_count = 0;
  double best_up = -2.0;
  for (std::size_t f = 0; f < A.face_normals.size(); ++f) {
    const Vec3& m = A.face_normals[f];
    const double up = m.dot(q.n);
    if (up > best_up) {
      best_up = up;
      q.face_a = static_cast<int>(f);
    }
    q.faces_up[up_count] = {m.dot(q.t), m.dot(q.s), up, A.face_offsets[f]};
    up_count += up > 1e-6 ? 1 : 0;
  }
  q.faces_up.resize(up_count);
  q.faces_down.resize(pair.nb.size());
  std::size_t down_count = 0;
  double best_down = 2.0;
  for (std::size_t f = 0; f < pair.nb.size(); ++f) {
    const Vec3& m = pair.nb[f];
    const double down = m.dot(q.n);
    if (down < best_down) {
      best_down = down;
      q.face_b = static_cast<int>(f);
    }
    q.faces_down[down_count] = {m.dot(q.t), m.dot(q.s), down, B.face_offsets[f] + m.dot(pair.translation)};
    down_count += down < -1e-6 ? 1 : 0;
  }
  q.faces_down.resize(down_count);
}

/// Sets the plane's frame in A's frame and what every stage reads: each vertex's height along n
/// (computed once, read by the caps, the ridges and the vertex points), the extremes, the surfaces.
void place_on_plane(const PolyhedronPair& pair, const Vec3& normal_world, PairOnPlane& q) {
  const ConvexPolyhedron& A = *pair.A;
  const ConvexPolyhedron& B = *pair.B;
  q.pair = &pair;
  q.size = std::min(A.bounding_radius, B.bounding_radius);
  q.n = pair.rotation_a.transpose() * normal_world;
  const Mat3 plane = frame_from_normal(q.n);
  q.t = plane.col(1);
  q.s = plane.col(2);
  q.heights_a.resize(A.vertices.size());
  q.top_a = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < A.vertices.size(); ++i) {
    q.heights_a[i] = q.n.dot(A.vertices[i]);
    q.top_a = std::max(q.top_a, q.heights_a[i]);
  }
  q.heights_b.resize(pair.vb.size());
  q.bottom_b = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < pair.vb.size(); ++i) {
    q.heights_b[i] = q.n.dot(pair.vb[i]);
    q.bottom_b = std::min(q.bottom_b, q.heights_b[i]);
  }
  q.linear_tolerance = 1e-7 * q.size;
  q.feature_tolerance = 1e-3 * q.size;
  surfaces_on_plane(q);
}

/// Plane coordinates of the vertices within `depth` of their body's extreme (the deepest caps
/// and ridges read no others): each computed once, not once per cap. Their indices, in increasing
/// order, go to cap_vertices_a / cap_vertices_b, so that the caps and ridges visit these few
/// vertices and not the whole body.
void project_cap_vertices(PairOnPlane& q, double depth) {
  const PolyhedronPair& pair = *q.pair;
  q.plane_a.resize(q.heights_a.size());
  q.cap_vertices_a.clear();
  for (std::size_t i = 0; i < q.heights_a.size(); ++i) {
    if (q.heights_a[i] < q.top_a - depth) continue;
    const Vec3& v = pair.A->vertices[i];
    q.plane_a[i] = Vec2(q.t.dot(v), q.s.dot(v));
    q.cap_vertices_a.push_back(static_cast<int>(i));
  }
  q.plane_b.resize(q.heights_b.size());
  q.cap_vertices_b.clear();
  for (std::size_t i = 0; i < q.heights_b.size(); ++i) {
    if (q.heights_b[i] > q.bottom_b + depth) continue;
    const Vec3& v = pair.vb[i];
    q.plane_b[i] = Vec2(q.t.dot(v), q.s.dot(v));
    q.cap_vertices_b.push_back(static_cast<int>(i));
  }
}

/// A's upper surface above the plane point p: the lower envelope of its faces turned towards n.
double height_a(const PairOnPlane& q, const Vec2& p) {
  double z = std::numeric_limits<double>::infinity();
  for (const auto& m : q.faces_up) z = std::min(z, (m[3] - p.x() * m[0] - p.y() * m[1]) / m[2]);
  return z;
}

/// B's lower surface below the plane point p: the upper envelope of its faces turned against n.
double height_b(const PairOnPlane& q, const Vec2& p) {
  double z = -std::numeric_limits<double>::infinity();
  for (const auto& m : q.faces_down) z = std::max(z, (m[3] - p.x() * m[0] - p.y() * m[1]) / m[2]);
  return z;
}

/// The caps of A and B: their vertices within `depth` of the body's extreme along n, projected
/// on the plane, as convex hulls (into cap_a and cap_b). `depth` is at most the depth given to
/// project_cap_vertices.
void caps(PairOnPlane& q, double depth, Polygon& cap_a, Polygon& cap_b) {
  q.cap_a.clear();
  for (const int i : q.cap_vertices_a) {
    if (q.heights_a[static_cast<std::size_t>(i)] >= q.top_a - depth)
      q.cap_a.push_back({q.plane_a[static_cast<std::size_t>(i)], i});
  }
  q.cap_b.clear();
  for (const int i : q.cap_vertices_b) {
    if (q.heights_b[static_cast<std::size_t>(i)] <= q.bottom_b + depth)
      q.cap_b.push_back({q.plane_b[static_cast<std::size_t>(i)], i});
  }
  hull_2d(q.cap_a, q.linear_tolerance, cap_a, q.hull);
  hull_2d(q.cap_b, q.linear_tolerance, cap_b, q.hull);
}

/// Does a candidate lie within the feature tolerance of plane point p already (coincident
/// features)? Asked before the surface heights are computed: the support and alert caps and
/// the ridges find many of the same points, and a height costs a division per face.
bool coincides(const PairOnPlane& q, const Vec2& p, const std::vector<Candidate>& candidates) {
  const double tolerance2 = q.feature_tolerance * q.feature_tolerance;
  for (const Candidate& c : candidates) {
    if ((c.p - p).squaredNorm() <= tolerance2) return true;
  }
  return false;
}

/// Adds the candidate at plane point p (surface heights za of A, zb of B) unless one lies within
/// the feature tolerance already (coincident features).
void add_candidate(const PairOnPlane& q, const Vec2& p, double za, double zb, std::uint32_t feature_a,
                   std::uint32_t feature_b, std::vector<Candidate>& candidates) {
  if (coincides(q, p, candidates)) return;
  candidates.push_back({p, zb - za, za, zb, feature_a, feature_b});
}

/// The points of the intersection of two cap polygons: the vertices of each inside the other,
/// then the crossings of their edges.
void add_polygon_intersection(const PairOnPlane& q, const Polygon& polygon_a, const Polygon& polygon_b,
                              std::vector<Candidate>& candidates) {
  const std::size_t vertices_a = q.heights_a.size(), vertices_b = q.heights_b.size();
  for (const CapVertex& c : polygon_a) {
    if (inside(polygon_b, c.p, q.feature_tolerance) && !coincides(q, c.p, candidates)) {
      add_candidate(q, c.p, q.heights_a[static_cast<std::size_t>(c.vertex)], height_b(q, clamp_into(polygon_b, c.p)),
                    vertex_code(c.vertex), face_code(q.face_b), candidates);
    }
  }
  for (const CapVertex& c : polygon_b) {
    if (inside(polygon_a, c.p, q.feature_tolerance) && !coincides(q, c.p, candidates)) {
      add_candidate(q, c.p, height_a(q, clamp_into(polygon_a, c.p)), q.heights_b[static_cast<std::size_t>(c.vertex)],
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
      if (!segments_cross(a0.p, a1.p, b0.p, b1.p, at) || coincides(q, at, candidates)) continue;
      // The cap hull's edges may be chords across a curved cap: take the surfaces' heights
      // there (exact on a true edge, and above a chord).
      const double za = height_a(q, at);
      const double zb = height_b(q, at);
      add_candidate(q, at, za, zb, edge_code(a0.vertex, a1.vertex, vertices_a),
                    edge_code(b0.vertex, b1.vertex, vertices_b), candidates);
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
    const Vec2 c = closest_on_boundary(polygon_b, x.p, q.heights_b.size(), f);
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
    const Vec2 c = closest_on_boundary(polygon_a, y.p, q.heights_a.size(), f);
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
/// Adds the crossings of the edges of A and B within `depth` of their extremes (a ridge is kept
/// as its two ends, consecutive in ridges_a / ridges_b).
void add_ridge_crossings(PairOnPlane& q, double depth) {
  const ConvexPolyhedron& A = *q.pair->A;
  const ConvexPolyhedron& B = *q.pair->B;
  // A ridge joins two cap vertices: found from the cap's vertices (i < j, in increasing order)
  // through the vertex graph instead of a scan of every edge.
  q.ridges_a.clear();
  for (const int i : q.cap_vertices_a) {
    for (const int j : A.vertex_neighbours[static_cast<std::size_t>(i)]) {
      if (j <= i || q.heights_a[static_cast<std::size_t>(j)] < q.top_a - depth) continue;
      q.ridges_a.push_back({q.plane_a[static_cast<std::size_t>(i)], i});
      q.ridges_a.push_back({q.plane_a[static_cast<std::size_t>(j)], j});
    }
  }
  q.ridges_b.clear();
  for (const int i : q.cap_vertices_b) {
    for (const int j : B.vertex_neighbours[static_cast<std::size_t>(i)]) {
      if (j <= i || q.heights_b[static_cast<std::size_t>(j)] > q.bottom_b + depth) continue;
      q.ridges_b.push_back({q.plane_b[static_cast<std::size_t>(i)], i});
      q.ridges_b.push_back({q.plane_b[static_cast<std::size_t>(j)], j});
    }
  }
  for (std::size_t ea = 0; ea < q.ridges_a.size(); ea += 2) {
    const CapVertex& from_a = q.ridges_a[ea];
    const CapVertex& to_a = q.ridges_a[ea + 1];
    for (std::size_t eb = 0; eb < q.ridges_b.size(); eb += 2) {
      const CapVertex& from_b = q.ridges_b[eb];
      const CapVertex& to_b = q.ridges_b[eb + 1];
      Vec2 at;
      if (!segments_cross(from_a.p, to_a.p, from_b.p, to_b.p, at) || coincides(q, at, q.candidates)) continue;
      add_candidate(q, at, height_a(q, at), height_b(q, at), edge_code(from_a.vertex, to_a.vertex, A.vertices.size()),
                    edge_code(from_b.vertex, to_b.vertex, B.vertices.size()), q.candidates);
    }
  }
}

/// Contact points of two polyhedra on their common plane (normal from A to B, separation `gap`):
/// the caps of A and B (vertices within the depth that can still give a local gap below the
/// alert distance) are projected on the plane, their convex polygons intersected (vertices of
/// one inside the other, crossings of their edges), and each point of the intersection gets
/// its local gap from the two bodies' surfaces above and below it. Vertex-face gives 1 point,
/// edge-edge 1, edge-face 2, face-face the clipped polygon, reduced to <= 4 points. Reads B's
/// vertices as the common-plane search left them in A's frame (`pair`).
void contacts_on_common_plane(const PolyhedronPair& pair, std::uint32_t body_a, std::uint32_t body_b,
                              const Vec3& normal_world, double gap, double alert_distance, PairOnPlane& q,
                              ContactList& contacts) {
  place_on_plane(pair, normal_world, q);
  // Two sets of caps: the support features (depth ~ 0), whose overlap holds the deepest point
  // (at the optimal plane the supports' projections meet), and the alert caps, which add the
  // points of a nearly flush face that may close within the alert distance: a local gap below
  // the alert distance needs depth_a + depth_b < alert - gap. Alert caps are measured as if the
  // bodies touched (gap clamped at 0), so a deep overlap does not turn them into curved patches
  // whose hull hides their lowest vertices.
  const double alert_depth = std::max(alert_distance - std::max(gap, 0.0), 0.0) + q.linear_tolerance;
  project_cap_vertices(q, alert_depth);
  caps(q, q.linear_tolerance, q.support_a, q.support_b);
  caps(q, alert_depth, q.alert_a, q.alert_b);
  q.candidates.clear();
  add_polygon_intersection(q, q.support_a, q.support_b, q.candidates);
  if (q.candidates.empty()) add_closest_features_point(q, q.support_a, q.support_b, q.candidates);
  add_polygon_intersection(q, q.alert_a, q.alert_b, q.candidates);
  add_ridge_crossings(q, alert_depth);

  q.active.clear();
  for (const Candidate& c : q.candidates) {
    if (c.gap < alert_distance) q.active.push_back(c);
  }
  reduce_to_four(q.active, 1e-12 * q.size * q.size, q.kept);
  add_off_plane_points(q.active, q.kept, std::max(q.linear_tolerance, 0.01 * alert_distance), max_points_per_pair,
                       q.reduction);
  const Mat3 frame = frame_from_normal(normal_world);
  for (const Candidate& c : q.kept) {
    const Vec3 local = c.p.x() * q.t + c.p.y() * q.s + 0.5 * (c.height_a + c.height_b) * q.n;
    push_contact(body_a, body_b, c.feature_a, c.feature_b, frame, pair.rotation_a * local + pair.position_a, c.gap,
                 contacts);
  }
}

/// The common plane of the pair placed in `scratch.pair` (bodies a, b), its normal into
/// `common_normal` (the warm-start memory), and its contact points when the plane is complete and
/// its gap within the alert distance.
void collide_placed_pair(std::uint32_t a, std::uint32_t b, double alert_distance, const Vec3* previous_common_normal,
                         ContactList& contacts, Vec3& common_normal, PolyhedronScratch& scratch) {
  const CommonPlane plane = find_common_plane(scratch.pair, previous_common_normal, alert_distance);
  common_normal = plane.normal;
  if (!plane.complete || plane.gap >= alert_distance) return;
  contacts_on_common_plane(scratch.pair, a, b, plane.normal, plane.gap, alert_distance, scratch.plane, contacts);
}

}  // namespace

void collide_polyhedron_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                                   double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                                   Vec3& common_normal, PolyhedronScratch& scratch) {
  // Bounding spheres first: most broad-phase pairs stop here.
  const double centre_distance = (state.position[b] - state.position[a]).norm();
  if (centre_distance - model.bounding_radius[a] - model.bounding_radius[b] >= alert_distance) return;
  place_pair(placed(model, state, a), placed(model, state, b), scratch.pair);
  collide_placed_pair(a, b, alert_distance, previous_common_normal, contacts, common_normal, scratch);
}

void collide_polyhedron_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                                   double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                                   Vec3& common_normal) {
  PolyhedronScratch scratch;
  collide_polyhedron_polyhedron(model, state, a, b, alert_distance, previous_common_normal, contacts, common_normal,
                                scratch);
}

void collide_box_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                            double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                            Vec3& common_normal, PolyhedronScratch& scratch) {
  // A box wall is a convex polyhedron with 8 vertices: the same common-plane method applies.
  const ConvexPolyhedron box =
      make_box_polyhedron(model.boxes[static_cast<std::size_t>(model.shape_index[wall])].half_extents);
  const PolyhedronInWorld pa{&box, state.position[wall], state.orientation[wall].toRotationMatrix()};
  place_pair(pa, placed(model, state, grain), scratch.pair);
  // The warm-start memory is keyed by the ordered pair; the dispatcher passes (wall, grain) and
  // stores the normal as returned here (from the wall to the grain).
  collide_placed_pair(wall, grain, alert_distance, previous_common_normal, contacts, common_normal, scratch);
}

void collide_box_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                            double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                            Vec3& common_normal) {
  PolyhedronScratch scratch;
  collide_box_polyhedron(model, state, wall, grain, alert_distance, previous_common_normal, contacts, common_normal,
                         scratch);
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
  // The polyhedron lies behind each of its face planes, so the deepest plane's distance bounds the
  // centre's distance to it from below: a pair beyond the alert distance by that bound needs no
  // closest point (GJK was 9 % of a step of LMGC90's mixed deposit, most of it on such pairs).
  if (signed_distance - radius >= alert_distance) return;
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
