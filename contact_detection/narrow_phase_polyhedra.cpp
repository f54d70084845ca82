#include "contact_detection/narrow_phase_polyhedra.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "contact_detection/common_plane.hpp"
#include "core/polyhedron.hpp"

namespace rubble {
namespace {

using Vec2 = Eigen::Vector2d;

// Feature codes of contact ids: the kind in the top two bits, an index below.
constexpr std::uint32_t kind_vertex = 0u << 30;
constexpr std::uint32_t kind_edge = 1u << 30;
constexpr std::uint32_t kind_face = 2u << 30;
constexpr std::uint32_t index_mask = (1u << 30) - 1u;

/// Contact points of one pair at most: 4 for a flat contact, more only where a curved cap's
/// gap is not affine over the plane (see add_off_plane_points).
constexpr std::size_t max_points_per_pair = 8;

std::uint32_t vertex_code(int v) { return kind_vertex | (static_cast<std::uint32_t>(v) & index_mask); }
std::uint32_t face_code(int f) { return kind_face | (static_cast<std::uint32_t>(f) & index_mask); }
/// An edge between vertices i and j of a polyhedron with n vertices (any pair: the edge of a
/// contact polygon may be a chord of a nearly flat cap).
std::uint32_t edge_code(int i, int j, std::size_t n) {
  const auto lo = static_cast<std::uint64_t>(std::min(i, j));
  const auto hi = static_cast<std::uint64_t>(std::max(i, j));
  return kind_edge | static_cast<std::uint32_t>((lo * n + hi) & index_mask);
}

PolyhedronInWorld placed(const Model& model, const State& state, std::uint32_t body) {
  return {&model.polyhedra[static_cast<std::size_t>(model.shape_index[body])], state.position[body],
          state.orientation[body].toRotationMatrix()};
}

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// A vertex of a contact polygon: its plane coordinates and the polyhedron vertex it comes from.
struct CapVertex {
  Vec2 p;
  int vertex = 0;
};

/// Convex hull (counter-clockwise, Andrew's monotone chain) of the cap's projections; points
/// closer than `tolerance` to a hull edge's line are dropped, so a flat cap collapses to a
/// segment (2 points) or a point (1).
std::vector<CapVertex> hull_2d(std::vector<CapVertex> points, double tolerance) {
  std::sort(points.begin(), points.end(), [](const CapVertex& a, const CapVertex& b) {
    return a.p.x() < b.p.x() ||
           (a.p.x() == b.p.x() && (a.p.y() < b.p.y() || (a.p.y() == b.p.y() && a.vertex < b.vertex)));
  });
  // Merge coincident points (keep the lowest vertex id for determinism).
  std::vector<CapVertex> unique;
  for (const CapVertex& c : points) {
    bool found = false;
    for (CapVertex& u : unique) {
      if ((u.p - c.p).norm() <= tolerance) {
        found = true;
        u.vertex = std::min(u.vertex, c.vertex);
        break;
      }
    }
    if (!found) unique.push_back(c);
  }
  if (unique.size() <= 2) return unique;
  std::vector<CapVertex> hull(2 * unique.size());
  std::size_t k = 0;
  auto turn = [&](const CapVertex& o, const CapVertex& a, const CapVertex& b) {
    const Vec2 oa = a.p - o.p;
    const Vec2 ob = b.p - o.p;
    // Left turn by more than the tolerance (distance of b from the line o-a).
    return cross2(oa, ob) > tolerance * oa.norm();
  };
  for (const CapVertex& c : unique) {
    while (k >= 2 && !turn(hull[k - 2], hull[k - 1], c)) --k;
    hull[k++] = c;
  }
  for (std::size_t i = unique.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && !turn(hull[k - 2], hull[k - 1], unique[i])) --k;
    hull[k++] = unique[i];
  }
  hull.resize(k - 1);
  if (hull.size() < 2) hull.assign(1, unique.front());
  return hull;
}

/// Is q inside the convex polygon (or on the segment / at the point) within `tolerance`?
bool inside(const std::vector<CapVertex>& polygon, const Vec2& q, double tolerance) {
  if (polygon.size() == 1) return (q - polygon[0].p).norm() <= tolerance;
  if (polygon.size() == 2) {
    const Vec2 d = polygon[1].p - polygon[0].p;
    const double t = std::clamp((q - polygon[0].p).dot(d) / d.squaredNorm(), 0.0, 1.0);
    return (polygon[0].p + t * d - q).norm() <= tolerance;
  }
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Vec2& a = polygon[i].p;
    const Vec2& b = polygon[(i + 1) % polygon.size()].p;
    const Vec2 e = b - a;
    if (cross2(e, q - a) < -tolerance * e.norm()) return false;
  }
  return true;
}

/// Closest point to q on the boundary of `polygon` (a point, segment or polygon), with its feature
/// code (vertex or edge of a body with `vertex_count` vertices).
Vec2 closest_on_boundary(const std::vector<CapVertex>& polygon, const Vec2& q, std::size_t vertex_count,
                         std::uint32_t& feature) {
  Vec2 best_point = polygon[0].p;
  double best_distance = (q - best_point).squaredNorm();
  feature = vertex_code(polygon[0].vertex);
  const std::size_t edges = polygon.size() < 2 ? 0 : (polygon.size() == 2 ? 1 : polygon.size());
  for (std::size_t i = 0; i < edges; ++i) {
    const CapVertex& p0 = polygon[i];
    const CapVertex& p1 = polygon[(i + 1) % polygon.size()];
    const Vec2 e = p1.p - p0.p;
    const double t = std::clamp((q - p0.p).dot(e) / e.squaredNorm(), 0.0, 1.0);
    const Vec2 c = p0.p + t * e;
    const double d = (q - c).squaredNorm();
    if (d < best_distance) {
      best_distance = d;
      best_point = c;
      feature = t == 0.0   ? vertex_code(p0.vertex)
                : t == 1.0 ? vertex_code(p1.vertex)
                           : edge_code(p0.vertex, p1.vertex, vertex_count);
    }
  }
  return best_point;
}

/// q itself when it lies in `polygon`, else the closest point of the polygon. A vertex accepted
/// as "inside" within the feature tolerance lies just beyond the other body's footprint, where
/// that body's surface height would come from a nearly parallel side face (height ~ offset /
/// tiny slope, i.e. a huge bogus gap); its height is read at the footprint's edge instead.
Vec2 clamp_into(const std::vector<CapVertex>& polygon, const Vec2& q) {
  if (polygon.size() >= 3 && inside(polygon, q, 0.0)) return q;
  std::uint32_t feature = 0;
  return closest_on_boundary(polygon, q, 0, feature);
}

/// Proper crossing of segments a0-a1 and b0-b1 (parallel segments never cross: their overlap is
/// found through the endpoint-inside tests).
bool segments_cross(const Vec2& a0, const Vec2& a1, const Vec2& b0, const Vec2& b1, Vec2& at, double& t_a) {
  const Vec2 r = a1 - a0;
  const Vec2 s = b1 - b0;
  const double denominator = cross2(r, s);
  if (std::abs(denominator) <= 1e-12 * r.norm() * s.norm()) return false;
  const Vec2 w = b0 - a0;
  const double t = cross2(w, s) / denominator;
  const double u = cross2(w, r) / denominator;
  if (t < 0.0 || t > 1.0 || u < 0.0 || u > 1.0) return false;
  at = a0 + t * r;
  t_a = t;
  return true;
}

/// A candidate contact point on the common plane.
struct Candidate {
  Vec2 p;                 ///< plane coordinates
  double gap = 0.0;       ///< local gap
  double height_a = 0.0;  ///< height of A's surface along n
  double height_b = 0.0;  ///< height of B's surface along n
  std::uint32_t feature_a = 0;
  std::uint32_t feature_b = 0;
};

double polygon_area(std::vector<CapVertex> points) {
  const std::vector<CapVertex> hull = hull_2d(std::move(points), 0.0);
  double area = 0.0;
  for (std::size_t i = 0; i < hull.size() && hull.size() >= 3; ++i) {
    area += cross2(hull[i].p, hull[(i + 1) % hull.size()].p);
  }
  return 0.5 * std::abs(area);
}

/// Keeps at most 4 candidates carrying the contact area: the deepest point first, then the
/// point farthest from it, then the one spanning the largest triangle with them, then the one
/// adding the most area (dropped when it adds nothing). Deterministic for a given input order.
std::vector<Candidate> reduce_to_four(const std::vector<Candidate>& all, double area_tolerance) {
  if (all.size() <= 4) return all;
  std::size_t i1 = 0;
  for (std::size_t i = 1; i < all.size(); ++i) {
    if (all[i].gap < all[i1].gap) i1 = i;
  }
  std::size_t i2 = i1;
  double far = -1.0;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const double d = (all[i].p - all[i1].p).squaredNorm();
    if (d > far) {
      far = d;
      i2 = i;
    }
  }
  std::size_t i3 = i1;
  double area3 = -1.0;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const double a = std::abs(cross2(all[i2].p - all[i1].p, all[i].p - all[i1].p));
    if (a > area3) {
      area3 = a;
      i3 = i;
    }
  }
  std::vector<Candidate> kept{all[i1], all[i2]};
  if (area3 <= area_tolerance) return kept;  // all collinear: a segment
  kept.push_back(all[i3]);
  const double triangle = 0.5 * area3;
  std::size_t i4 = all.size();
  double best_gain = area_tolerance;
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (i == i1 || i == i2 || i == i3) continue;
    const double gain = polygon_area({{all[i1].p, 0}, {all[i2].p, 1}, {all[i3].p, 2}, {all[i].p, 3}}) - triangle;
    if (gain > best_gain) {
      best_gain = gain;
      i4 = i;
    }
  }
  if (i4 < all.size()) kept.push_back(all[i4]);
  return kept;
}

/// The points `reduce_to_four` dropped that the kept ones do not stand for. A rigid relative
/// motion changes the gap affinely over the plane, so constraints at the kept points hold every
/// point whose gap lies on the affine fit of the kept points' gaps (a flat face-face contact: all
/// of them). A curved cap's gap is convex, below that fit between kinks, and a point deeper than
/// the fit by more than `tolerance` could sink by that much within one step: it is kept too,
/// deepest deficit first, up to `max_points` in all.
std::vector<Candidate> add_off_plane_points(const std::vector<Candidate>& all, std::vector<Candidate> kept,
                                            double tolerance, std::size_t max_points) {
  if (kept.size() == all.size() || kept.size() >= max_points) return kept;
  // Affine fit gap ~ c0 + c1 x + c2 y by least squares over the kept points (a line or a
  // constant when they are collinear or alone).
  const Vec2 origin = kept[0].p;
  Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
  Vec3 right = Vec3::Zero();
  for (const Candidate& c : kept) {
    const Vec3 row(1.0, c.p.x() - origin.x(), c.p.y() - origin.y());
    normal_matrix += row * row.transpose();
    right += row * c.gap;
  }
  const Eigen::CompleteOrthogonalDecomposition<Eigen::Matrix3d> solver(normal_matrix);
  const Vec3 fit = solver.solve(right);
  std::vector<std::pair<double, std::size_t>> deficits;
  for (std::size_t i = 0; i < all.size(); ++i) {
    bool is_kept = false;
    for (const Candidate& c : kept) is_kept = is_kept || (c.p - all[i].p).squaredNorm() == 0.0;
    if (is_kept) continue;
    const double predicted = fit.dot(Vec3(1.0, all[i].p.x() - origin.x(), all[i].p.y() - origin.y()));
    const double deficit = predicted - all[i].gap;
    if (deficit > tolerance) deficits.emplace_back(deficit, i);
  }
  std::sort(deficits.begin(), deficits.end(), [](const auto& x, const auto& y) {
    return x.first > y.first || (x.first == y.first && x.second < y.second);
  });
  for (const auto& [deficit, i] : deficits) {
    if (kept.size() >= max_points) break;
    kept.push_back(all[i]);
  }
  return kept;
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

/// Contact points of two polyhedra on their common plane (normal from A to B, separation `gap`):
/// the caps of A and B (vertices within the depth that can still give a local gap below the
/// alert distance) are projected on the plane, their convex polygons intersected (vertices of
/// one inside the other, crossings of their edges), and each point of the intersection gets
/// its local gap from the two bodies' surfaces above and below it. Vertex-face gives 1 point,
/// edge-edge 1, edge-face 2, face-face the clipped polygon, reduced to <= 4 points.
// NOLINTNEXTLINE(readability-function-size): over 80 lines, listed in docs/architecture.md
void contacts_on_common_plane(const PolyhedronInWorld& pa, const PolyhedronInWorld& pb, std::uint32_t body_a,
                              std::uint32_t body_b, const Vec3& normal_world, double gap, double alert_distance,
                              ContactList& contacts) {
  const ConvexPolyhedron& A = *pa.shape;
  const ConvexPolyhedron& B = *pb.shape;
  const Mat3 rotation = pa.rotation.transpose() * pb.rotation;
  const Vec3 translation = pa.rotation.transpose() * (pb.position - pa.position);
  const double size = std::min(A.bounding_radius, B.bounding_radius);
  const Vec3 n = pa.rotation.transpose() * normal_world;  // in A's frame
  const Mat3 plane = frame_from_normal(n);
  const Vec3 t = plane.col(1);
  const Vec3 s = plane.col(2);

  std::vector<Vec3> vb(B.vertices.size());
  for (std::size_t i = 0; i < vb.size(); ++i) vb[i] = rotation * B.vertices[i] + translation;
  double top_a = -std::numeric_limits<double>::infinity();
  for (const Vec3& v : A.vertices) top_a = std::max(top_a, n.dot(v));
  double bottom_b = std::numeric_limits<double>::infinity();
  for (const Vec3& v : vb) bottom_b = std::min(bottom_b, n.dot(v));

  // Cap depth: a local gap below the alert distance needs depth_a + depth_b < alert - gap.
  const double linear_tolerance = 1e-7 * size;
  // Features closer than this in the plane count as coincident, and a vertex this close outside
  // the other polygon still counts as inside: stacked, aligned faces then keep the same contact
  // ids (hence warm starts) while they creep by less than 1e-3 of the grain size.
  const double feature_tolerance = 1e-3 * size;
  // Two sets of caps (vertices within a depth of the body's extreme along n, projected on the
  // plane, convex hull): the support features (depth ~ 0), whose overlap holds the deepest point
  // (at the optimal plane the supports' projections meet), and the alert caps, which add the
  // points of a nearly flush face that may close within the alert distance. Alert caps are
  // measured as if the bodies touched (gap clamped at 0), so a deep overlap does not turn them
  // into curved patches whose hull hides their lowest vertices.
  auto caps = [&](double depth) {
    std::vector<CapVertex> cap_a, cap_b;
    for (std::size_t i = 0; i < A.vertices.size(); ++i) {
      if (n.dot(A.vertices[i]) >= top_a - depth)
        cap_a.push_back({Vec2(t.dot(A.vertices[i]), s.dot(A.vertices[i])), static_cast<int>(i)});
    }
    for (std::size_t i = 0; i < vb.size(); ++i) {
      if (n.dot(vb[i]) <= bottom_b + depth) cap_b.push_back({Vec2(t.dot(vb[i]), s.dot(vb[i])), static_cast<int>(i)});
    }
    return std::make_pair(hull_2d(std::move(cap_a), linear_tolerance), hull_2d(std::move(cap_b), linear_tolerance));
  };
  const auto support_polygons = caps(linear_tolerance);
  const auto alert_polygons = caps(std::max(alert_distance - std::max(gap, 0.0), 0.0) + linear_tolerance);

  // Surfaces above/below a plane point (u, v): A's upper surface is the lower envelope of its
  // faces turned towards n, B's lower surface the upper envelope of its faces turned against n.
  auto height_a = [&](const Vec2& p) {
    double z = std::numeric_limits<double>::infinity();
    for (std::size_t f = 0; f < A.face_normals.size(); ++f) {
      const Vec3& m = A.face_normals[f];
      const double up = m.dot(n);
      if (up <= 1e-6) continue;
      z = std::min(z, (A.face_offsets[f] - p.x() * m.dot(t) - p.y() * m.dot(s)) / up);
    }
    return z;
  };
  // Each face turned against n, as (m.t, m.s, m.n, offset) in A's frame, computed once.
  std::vector<std::array<double, 4>> faces_down;
  for (std::size_t f = 0; f < B.face_normals.size(); ++f) {
    const Vec3 m = rotation * B.face_normals[f];
    const double down = m.dot(n);
    if (down >= -1e-6) continue;
    faces_down.push_back({m.dot(t), m.dot(s), down, B.face_offsets[f] + m.dot(translation)});
  }
  auto height_b = [&](const Vec2& p) {
    double z = -std::numeric_limits<double>::infinity();
    for (const auto& m : faces_down) z = std::max(z, (m[3] - p.x() * m[0] - p.y() * m[1]) / m[2]);
    return z;
  };
  // The faces most turned towards each other name the "face" side of vertex-face points.
  int face_a = 0;
  double best_up = -2.0;
  for (std::size_t f = 0; f < A.face_normals.size(); ++f) {
    if (A.face_normals[f].dot(n) > best_up) {
      best_up = A.face_normals[f].dot(n);
      face_a = static_cast<int>(f);
    }
  }
  int face_b = 0;
  double best_down = 2.0;
  for (std::size_t f = 0; f < B.face_normals.size(); ++f) {
    const double d = (rotation * B.face_normals[f]).dot(n);
    if (d < best_down) {
      best_down = d;
      face_b = static_cast<int>(f);
    }
  }

  std::vector<Candidate> candidates;
  auto add = [&](const Vec2& p, double za, double zb, std::uint32_t fa, std::uint32_t fb) {
    for (const Candidate& c : candidates) {
      if ((c.p - p).norm() <= feature_tolerance) return;  // already there (coincident features)
    }
    candidates.push_back({p, zb - za, za, zb, fa, fb});
  };
  auto intersect = [&](const std::vector<CapVertex>& polygon_a, const std::vector<CapVertex>& polygon_b) {
    for (const CapVertex& c : polygon_a) {
      if (inside(polygon_b, c.p, feature_tolerance)) {
        add(c.p, n.dot(A.vertices[static_cast<std::size_t>(c.vertex)]), height_b(clamp_into(polygon_b, c.p)),
            vertex_code(c.vertex), face_code(face_b));
      }
    }
    for (const CapVertex& c : polygon_b) {
      if (inside(polygon_a, c.p, feature_tolerance)) {
        add(c.p, height_a(clamp_into(polygon_a, c.p)), n.dot(vb[static_cast<std::size_t>(c.vertex)]), face_code(face_a),
            vertex_code(c.vertex));
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
        double ta = 0.0;
        if (!segments_cross(a0.p, a1.p, b0.p, b1.p, at, ta)) continue;
        // The cap hull's edges may be chords across a curved cap: take the surfaces' heights
        // there (exact on a true edge, and above a chord).
        (void)ta;
        const double za = height_a(at);
        const double zb = height_b(at);
        add(at, za, zb, edge_code(a0.vertex, a1.vertex, A.vertices.size()),
            edge_code(b0.vertex, b1.vertex, B.vertices.size()));
      }
    }
  };
  intersect(support_polygons.first, support_polygons.second);
  if (candidates.empty()) {
    // The supports' projections do not meet (round-off, or a merged face bending the Gauss map):
    // one point between their closest features, carrying the plane's gap, so the overlap
    // measured by the common plane is always represented.
    const auto& polygon_a = support_polygons.first;
    const auto& polygon_b = support_polygons.second;
    double best = std::numeric_limits<double>::infinity();
    Vec2 point_a = polygon_a[0].p, point_b = polygon_b[0].p;
    std::uint32_t feature_a = vertex_code(polygon_a[0].vertex), feature_b = vertex_code(polygon_b[0].vertex);
    for (const CapVertex& x : polygon_a) {
      std::uint32_t f = 0;
      const Vec2 c = closest_on_boundary(polygon_b, x.p, B.vertices.size(), f);
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
      const Vec2 c = closest_on_boundary(polygon_a, y.p, A.vertices.size(), f);
      if ((c - y.p).squaredNorm() < best) {
        best = (c - y.p).squaredNorm();
        point_a = c;
        point_b = y.p;
        feature_a = f;
        feature_b = vertex_code(y.vertex);
      }
    }
    add(0.5 * (point_a + point_b), top_a, bottom_b, feature_a, feature_b);
  }
  intersect(alert_polygons.first, alert_polygons.second);
  // Ridges inside the caps: where an edge of one body crosses a curved cap of the other, the gap
  // along it has its kinks (and the overlap its corners) at the cap's interior edges, which the
  // hulls above do not see; missing them lets a sliding edge sink into the next facet in one step.
  {
    const double depth = std::max(alert_distance - std::max(gap, 0.0), 0.0) + linear_tolerance;
    struct Segment {
      CapVertex from, to;
    };
    std::vector<Segment> ridges_a, ridges_b;
    for (const auto& [i, j] : A.edges) {
      const Vec3& x = A.vertices[static_cast<std::size_t>(i)];
      const Vec3& y = A.vertices[static_cast<std::size_t>(j)];
      if (n.dot(x) < top_a - depth || n.dot(y) < top_a - depth) continue;
      ridges_a.push_back({{Vec2(t.dot(x), s.dot(x)), i}, {Vec2(t.dot(y), s.dot(y)), j}});
    }
    for (const auto& [i, j] : B.edges) {
      const Vec3& x = vb[static_cast<std::size_t>(i)];
      const Vec3& y = vb[static_cast<std::size_t>(j)];
      if (n.dot(x) > bottom_b + depth || n.dot(y) > bottom_b + depth) continue;
      ridges_b.push_back({{Vec2(t.dot(x), s.dot(x)), i}, {Vec2(t.dot(y), s.dot(y)), j}});
    }
    for (const Segment& ea : ridges_a) {
      for (const Segment& eb : ridges_b) {
        Vec2 at;
        double ta = 0.0;
        if (!segments_cross(ea.from.p, ea.to.p, eb.from.p, eb.to.p, at, ta)) continue;
        add(at, height_a(at), height_b(at), edge_code(ea.from.vertex, ea.to.vertex, A.vertices.size()),
            edge_code(eb.from.vertex, eb.to.vertex, B.vertices.size()));
      }
    }
  }

  std::vector<Candidate> active;
  for (const Candidate& c : candidates) {
    if (c.gap < alert_distance) active.push_back(c);
  }
  const std::vector<Candidate> kept =
      add_off_plane_points(active, reduce_to_four(active, 1e-12 * size * size),
                           std::max(linear_tolerance, 0.01 * alert_distance), max_points_per_pair);
  for (const Candidate& c : kept) {
    const Vec3 local = c.p.x() * t + c.p.y() * s + 0.5 * (c.height_a + c.height_b) * n;
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
