#include "contact_detection/common_plane.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <vector>

namespace rubble {
namespace {

constexpr double infinity = std::numeric_limits<double>::infinity();

double max_dot(const std::vector<Vec3>& points, const Vec3& n, int* index = nullptr) {
  double best = -infinity;
  int arg = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double h = n.dot(points[i]);
    if (h > best) {
      best = h;
      arg = static_cast<int>(i);
    }
  }
  if (index) *index = arg;
  return best;
}

double min_dot(const std::vector<Vec3>& points, const Vec3& n, int* index = nullptr) {
  double best = infinity;
  int arg = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double h = n.dot(points[i]);
    if (h < best) {
      best = h;
      arg = static_cast<int>(i);
    }
  }
  if (index) *index = arg;
  return best;
}

/// Liang-Barsky slab test: does the segment p-q meet the box [lower, upper]?
bool segment_meets_box(const Vec3& p, const Vec3& q, const Vec3& lower, const Vec3& upper) {
  double t_min = 0.0;
  double t_max = 1.0;
  const Vec3 d = q - p;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-300) {
      if (p[k] < lower[k] || p[k] > upper[k]) return false;
      continue;
    }
    double t1 = (lower[k] - p[k]) / d[k];
    double t2 = (upper[k] - p[k]) / d[k];
    if (t1 > t2) std::swap(t1, t2);
    t_min = std::max(t_min, t1);
    t_max = std::min(t_max, t2);
    if (t_min > t_max) return false;
  }
  return true;
}

/// Do the arcs (a1, a2) and (c1, c2) cross on the unit sphere? a2 x a1 and c2 x c1 are passed
/// precomputed. Two arcs cross iff each great circle separates the other arc's ends and the
/// crossing is not the antipodal one (Gregorius 2013, "The separating axis test between convex
/// polyhedra", GDC).
bool arcs_cross(const Vec3& a1, const Vec3& a2, const Vec3& a2_x_a1, const Vec3& c1, const Vec3& c2,
                const Vec3& c2_x_c1) {
  const double c1a = c1.dot(a2_x_a1);
  const double c2a = c2.dot(a2_x_a1);
  const double a1c = a1.dot(c2_x_c1);
  const double a2c = a2.dot(c2_x_c1);
  // The three tests are combined with & rather than &&: the first alone holds for a fair share of
  // the edge pairs, in no order a branch predictor can learn from pair to pair, and a missed
  // prediction costs more than the two dot products that short-circuiting saves (same answer).
  return static_cast<bool>(static_cast<int>(c1a * c2a < 0.0) & static_cast<int>(a1c * a2c < 0.0) &
                           static_cast<int>(c1a * a2c > 0.0));
}

// ----------------------------------------------------------------------------------------------
// GJK distance between A (points `a`) and B (points `b`), both in A's frame, on the Minkowski
// difference D = B - A. The simplex keeps the vertex pairs so the closest points can be read back.

struct SimplexVertex {
  Vec3 w = Vec3::Zero();  // b - a
  int ia = 0;             // vertex of A
  int ib = 0;             // vertex of B
};

struct GjkResult {
  bool separated = false;                // false: touching or overlapping (within round-off)
  Vec3 closest = Vec3::Zero();           // the point of D closest to the origin (direction A -> B)
  std::array<SimplexVertex, 4> simplex;  // the last simplex: support vertices near the contact
  int count = 0;                         // its vertex count
};

/// Closest point to the origin of the simplex s[0..count), reduced in place to the vertices
/// that support it (Ericson 2005, "Real-Time Collision Detection", sec. 5.1.2-5.1.6).
/// Returns false when the origin is inside a full tetrahedron.
// NOLINTNEXTLINE(readability-function-size): over 80 lines, listed in docs/architecture.md
bool reduce_simplex(std::array<SimplexVertex, 4>& s, int& count, Vec3& closest) {
  auto keep = [&](std::initializer_list<int> indices) {
    std::array<SimplexVertex, 4> kept;
    int k = 0;
    for (int i : indices) kept[static_cast<std::size_t>(k++)] = s[static_cast<std::size_t>(i)];
    s = kept;
    count = k;
  };
  auto segment = [&](int i, int j, Vec3& out) -> std::pair<double, int> {
    // Returns (t, which): which = 0 keeps i, 1 keeps j, 2 keeps both.
    const Vec3& a = s[static_cast<std::size_t>(i)].w;
    const Vec3 ab = s[static_cast<std::size_t>(j)].w - a;
    const double t = -a.dot(ab);
    if (t <= 0.0) {
      out = a;
      return {0.0, 0};
    }
    const double length2 = ab.squaredNorm();
    if (t >= length2) {
      out = a + ab;
      return {1.0, 1};
    }
    out = a + (t / length2) * ab;
    return {t / length2, 2};
  };
  auto triangle = [&](int ia, int ib, int ic, Vec3& out) -> int {
    // Region code: bit i set when vertex i of (a, b, c) is kept.
    const Vec3& a = s[static_cast<std::size_t>(ia)].w;
    const Vec3& b = s[static_cast<std::size_t>(ib)].w;
    const Vec3& c = s[static_cast<std::size_t>(ic)].w;
    const Vec3 ab = b - a, ac = c - a, ap = -a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
      out = a;
      return 1;
    }
    const Vec3 bp = -b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0.0 && d4 <= d3) {
      out = b;
      return 2;
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
      out = a + d1 / (d1 - d3) * ab;
      return 3;
    }
    const Vec3 cp = -c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0.0 && d5 <= d6) {
      out = c;
      return 4;
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
      out = a + d2 / (d2 - d6) * ac;
      return 5;
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
      out = b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
      return 6;
    }
    const double denominator = 1.0 / (va + vb + vc);
    out = a + ab * (vb * denominator) + ac * (vc * denominator);
    return 7;
  };
  auto keep_by_code = [&](std::array<int, 3> ids, int code) {
    std::array<SimplexVertex, 4> kept;
    int k = 0;
    for (int bit = 0; bit < 3; ++bit) {
      if (code & (1 << bit))
        kept[static_cast<std::size_t>(k++)] = s[static_cast<std::size_t>(ids[static_cast<std::size_t>(bit)])];
    }
    s = kept;
    count = k;
  };

  if (count == 1) {
    closest = s[0].w;
    return true;
  }
  if (count == 2) {
    const auto [t, which] = segment(0, 1, closest);
    (void)t;
    if (which == 0) keep({0});
    if (which == 1) keep({1});
    return true;
  }
  if (count == 3) {
    const int code = triangle(0, 1, 2, closest);
    keep_by_code({0, 1, 2}, code);
    return true;
  }
  // Tetrahedron: the closest point lies on a face the origin is outside of.
  const std::array<std::array<int, 4>, 4> faces = {{{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 3, 2, 0}}};
  double best = infinity;
  int best_face = -1;
  int best_code = 0;
  Vec3 best_point = Vec3::Zero();
  for (int f = 0; f < 4; ++f) {
    const auto& ids = faces[static_cast<std::size_t>(f)];
    const Vec3& a = s[static_cast<std::size_t>(ids[0])].w;
    const Vec3 n = (s[static_cast<std::size_t>(ids[1])].w - a).cross(s[static_cast<std::size_t>(ids[2])].w - a);
    const double side_origin = -a.dot(n);
    const double side_opposite = (s[static_cast<std::size_t>(ids[3])].w - a).dot(n);
    // Outside (or a flat tetrahedron, where every face counts as outside).
    if (side_origin * side_opposite < 0.0 || side_opposite == 0.0) {
      Vec3 point;
      const int code = triangle(ids[0], ids[1], ids[2], point);
      const double d2 = point.squaredNorm();
      if (d2 < best) {
        best = d2;
        best_face = f;
        best_code = code;
        best_point = point;
      }
    }
  }
  if (best_face < 0) return false;  // origin inside
  const auto& ids = faces[static_cast<std::size_t>(best_face)];
  keep_by_code({ids[0], ids[1], ids[2]}, best_code);
  closest = best_point;
  return true;
}

GjkResult gjk_distance(const std::vector<Vec3>& a, const std::vector<Vec3>& b, const Vec3& start_direction,
                       double size) {
  // Support of D in direction -v: the point of D with least projection on v.
  auto support = [&](const Vec3& v) {
    SimplexVertex out;
    max_dot(a, v, &out.ia);
    min_dot(b, v, &out.ib);
    out.w = b[static_cast<std::size_t>(out.ib)] - a[static_cast<std::size_t>(out.ia)];
    return out;
  };
  GjkResult result;
  std::array<SimplexVertex, 4> simplex;
  int count = 1;
  auto keep_simplex = [&](GjkResult& out) {
    out.simplex = simplex;
    out.count = count;
    return out;
  };
  simplex[0] = support(start_direction);
  Vec3 v = simplex[0].w;
  const double touching = 1e-12 * size;
  for (int iteration = 0; iteration < 64; ++iteration) {
    const double v2 = v.squaredNorm();
    if (v2 <= touching * touching) return keep_simplex(result);
    const SimplexVertex w = support(v);
    // Stop when the lower bound v.w/|v| has reached |v| to relative 1e-12 (Gilbert et al. 1988)
    // or the new support point is already in the simplex (no progress possible).
    if (v2 - v.dot(w.w) <= 1e-12 * v2) break;
    bool repeated = false;
    for (int i = 0; i < count; ++i) {
      if (simplex[static_cast<std::size_t>(i)].ia == w.ia && simplex[static_cast<std::size_t>(i)].ib == w.ib)
        repeated = true;
    }
    if (repeated) break;
    // Near convergence w lies almost in the plane of the last triangle, and round-off in the flat
    // tetrahedron they make can claim the origin inside or pick a wrong face, whose closest point
    // is then farther than v (seen: pairs 2e-5 d apart cycling to the iteration cap, or reported
    // overlapping). GJK's |v| must decrease (van den Bergen 2003, "Collision Detection in
    // Interactive 3D Environments", sec. 4.3.7): a step that does not is undone and the search
    // stops at the last simplex, converged as far as round-off allows.
    const std::array<SimplexVertex, 4> last_simplex = simplex;
    const int last_count = count;
    const Vec3 last_v = v;
    simplex[static_cast<std::size_t>(count++)] = w;
    const bool enclosed = !reduce_simplex(simplex, count, v);
    // Enclosed, unless w proves the contrary: w minimises v.x over D, so v.w > 0 puts all of D
    // beyond the plane v.x = 0, away from the origin (distance >= v.w / |v|).
    if (enclosed && last_v.dot(w.w) <= 0.0) return keep_simplex(result);  // origin enclosed: overlapping
    if (enclosed || v.squaredNorm() >= v2) {
      simplex = last_simplex;
      count = last_count;
      v = last_v;
      break;
    }
  }
  result.separated = v.norm() > touching;
  result.closest = v;
  return keep_simplex(result);
}

}  // namespace

bool closest_point_on_polyhedron(const ConvexPolyhedron& shape, const Vec3& point, Vec3& closest) {
  const std::vector<Vec3> single{point};
  const Vec3 start = point.squaredNorm() > 0.0 ? Vec3(point.normalized()) : Vec3::UnitZ();
  const GjkResult gjk = gjk_distance(shape.vertices, single, start, shape.bounding_radius);
  if (!gjk.separated) return false;
  closest = point - gjk.closest;  // closest = point - (closest point of the polyhedron)
  return true;
}

double plane_separation(const PolyhedronInWorld& a, const PolyhedronInWorld& b, const Vec3& normal) {
  double max_a = -infinity;
  const Vec3 na = a.rotation.transpose() * normal;
  for (const Vec3& v : a.shape->vertices) max_a = std::max(max_a, na.dot(v));
  double min_b = infinity;
  const Vec3 nb = b.rotation.transpose() * normal;
  for (const Vec3& v : b.shape->vertices) min_b = std::min(min_b, nb.dot(v));
  return (min_b + normal.dot(b.position)) - (max_a + normal.dot(a.position));
}

namespace {

/// The best plane found so far: f(normal) = value, and which candidate gave it.
struct BestPlane {
  double value = 0.0;                                        ///< m
  Vec3 normal;                                               ///< A's frame
  CommonPlaneSource source = CommonPlaneSource::warm_start;  ///< the candidate
};

/// f(n) = min_B n.y - max_A n.x, for n in A's frame.
double separation(const PolyhedronPair& q, const Vec3& n) { return min_dot(q.vb, n) - max_dot(q.A->vertices, n); }

/// Vertices of A and of B met by the warm start and by GJK: supports near the contact. Over any
/// subset of B's vertices the least n.y is at least the least over all of them (the same dot
/// products, in floating point too), and likewise for A's greatest; so the few witnesses bound a
/// candidate's f(n) from above exactly, and a candidate whose bound cannot beat the best is
/// skipped without its full support scans, with the same result (Ericson 2005, sec. 9.5 prunes
/// the same way).
struct Witnesses {
  std::array<int, 5> a{};  ///< vertices of A
  std::array<int, 5> b{};  ///< vertices of B
  int count = 0;           ///< used entries of a and b
};

/// The least n.y over B's witnesses (>= min_dot(q.vb, n)).
double witness_min_b(const PolyhedronPair& q, const Witnesses& w, const Vec3& n) {
  double least = infinity;
  for (int k = 0; k < w.count; ++k) least = std::min(least, n.dot(q.vb[static_cast<std::size_t>(w.b[k])]));
  return least;
}

/// The least n.x over A's witnesses (>= min_dot(A.vertices, n)).
double witness_min_a(const PolyhedronPair& q, const Witnesses& w, const Vec3& n) {
  double least = infinity;
  for (int k = 0; k < w.count; ++k) least = std::min(least, n.dot(q.A->vertices[static_cast<std::size_t>(w.a[k])]));
  return least;
}

/// The greatest n.x over A's witnesses (<= max_dot(A.vertices, n)).
double witness_max_a(const PolyhedronPair& q, const Witnesses& w, const Vec3& n) {
  double greatest = -infinity;
  for (int k = 0; k < w.count; ++k) {
    greatest = std::max(greatest, n.dot(q.A->vertices[static_cast<std::size_t>(w.a[k])]));
  }
  return greatest;
}

/// The face normals of A and (negated) of B as candidates. A face is skipped when a cheap bound
/// (the other body's centroid lies inside it) cannot beat the best value.
void search_face_normals(const PolyhedronPair& q, const Witnesses& w, BestPlane& best) {
  const ConvexPolyhedron& A = *q.A;
  const ConvexPolyhedron& B = *q.B;
  // Faces of A: f(n_f) = min_B n_f.y - d_f <= n_f.c_B - d_f since B's centroid is inside B.
  for (std::size_t f = 0; f < A.face_normals.size(); ++f) {
    const Vec3& n = A.face_normals[f];
    if (n.dot(q.translation) - A.face_offsets[f] <= best.value) continue;
    if (witness_min_b(q, w, n) - A.face_offsets[f] <= best.value) continue;
    const double value = min_dot(q.vb, n) - A.face_offsets[f];
    if (value > best.value) best = {value, n, CommonPlaneSource::face_a};
  }
  // Faces of B, normal -m: f = min_A m.x - (d_f + m.c_B) <= -(d_f + m.c_B) (A's centroid is 0).
  for (std::size_t f = 0; f < q.nb.size(); ++f) {
    const Vec3& m = q.nb[f];
    const double offset = B.face_offsets[f] + m.dot(q.translation);
    if (-offset <= best.value) continue;
    if (witness_min_a(q, w, m) - offset <= best.value) continue;
    const double value = min_dot(A.vertices, m) - offset;
    if (value > best.value) best = {value, -m, CommonPlaneSource::face_b};
  }
}

/// Outcode of p against the box [lower, upper] (Cohen-Sutherland; Ericson 2005, sec. 5.3.3 uses
/// the same slabs): bit 2k when p[k] < lower[k], bit 2k+1 when p[k] > upper[k].
unsigned char outcode(const Vec3& p, const Vec3& lower, const Vec3& upper) {
  unsigned code = 0;
  for (int k = 0; k < 3; ++k) {
    if (p[k] < lower[k]) code |= 1u << (2 * k);
    if (p[k] > upper[k]) code |= 2u << (2 * k);
  }
  return static_cast<unsigned char>(code);
}

/// segment_meets_box, answered from the endpoints' outcodes where they decide it. The slab test's
/// answer is "every slab's parameter interval meets [0, 1] and all of them meet each other", which
/// does not depend on the order of the axes; so (i) with both endpoints inside every slab it is
/// true, and (ii) with both beyond the same side of one slab, that slab's own interval, computed
/// with the same arithmetic, decides a rejection before the others. Same answer to the bit as
/// segment_meets_box, at a fraction of its cost (it was a fifth of the narrow phase).
bool segment_meets_box_coded(const Vec3& p, const Vec3& q, unsigned code_p, unsigned code_q, const Vec3& lower,
                             const Vec3& upper) {
  // p inside: t = 0 lies in every slab's interval (each slab gives t1 <= 0 <= t2).
  if (code_p == 0) return true;
  // q inside: t = 1 lies in every slab's interval (lower <= q gives (lower - p) / d <= 1 after
  // rounding, which is monotone), unless the segment is parallel to a slab that p lies outside.
  if (code_q == 0) {
    bool parallel_outside = false;
    for (int k = 0; k < 3; ++k) {
      if (((code_p >> (2 * k)) & 3u) != 0 && std::abs(q[k] - p[k]) < 1e-300) parallel_outside = true;
    }
    if (!parallel_outside) return true;
  }
  const unsigned common = code_p & code_q;
  if (common != 0) {
    const int k = std::countr_zero(common) / 2;
    const double d = q[k] - p[k];
    if (std::abs(d) < 1e-300) return false;  // outside the slab and parallel to it
    double t1 = (lower[k] - p[k]) / d;
    double t2 = (upper[k] - p[k]) / d;
    if (t1 > t2) std::swap(t1, t2);
    if (std::max(0.0, t1) > std::min(1.0, t2)) return false;
  }
  return segment_meets_box(p, q, lower, upper);
}

/// Outcode not computed yet (outcode() sets only the six low bits).
constexpr unsigned char unknown_outcode = 0xFF;

/// Fills q.edges_a and q.edges_b with the edges of A and of B that may carry a candidate beating
/// the best plane found so far (normal `normal`, A's frame). An edge pair whose value s beats the
/// best has crossing points x_A and x_B = x_A + s n with |s| < reach, so both edges pass within
/// reach of the other body, and two necessary conditions follow: (i) the edge meets the other
/// body's bounding box inflated by reach; (ii) along `normal`, where B lies above its least height
/// h_B and A below its greatest h_A, the edge of A reaches above h_B - reach and the edge of B below
/// h_A + reach. Test (ii) costs one dot product per vertex and, near contact, keeps only the edges
/// of the two thin caps facing each other; the box test (i) then moves only their ends.
void edges_within_reach(PolyhedronPair& q, const Vec3& normal, double reach) {
  const ConvexPolyhedron& A = *q.A;
  const ConvexPolyhedron& B = *q.B;
  q.heights_a.resize(A.vertices.size());
  double top_a = -infinity;
  for (std::size_t i = 0; i < A.vertices.size(); ++i) {
    q.heights_a[i] = normal.dot(A.vertices[i]);
    top_a = std::max(top_a, q.heights_a[i]);
  }
  q.heights_b.resize(q.vb.size());
  double bottom_b = infinity;
  for (std::size_t i = 0; i < q.vb.size(); ++i) {
    q.heights_b[i] = normal.dot(q.vb[i]);
    bottom_b = std::min(bottom_b, q.heights_b[i]);
  }
  const double floor_a = bottom_b - reach, ceiling_b = top_a + reach;
  const Vec3 lower_b = B.box_min - Vec3::Constant(reach), upper_b = B.box_max + Vec3::Constant(reach);
  const Vec3 lower_a = A.box_min - Vec3::Constant(reach), upper_a = A.box_max + Vec3::Constant(reach);
  q.va_in_b.resize(A.vertices.size());
  q.outcodes_a.assign(A.vertices.size(), unknown_outcode);
  auto classify_a = [&](std::size_t i) {
    if (q.outcodes_a[i] == unknown_outcode) {
      q.va_in_b[i] = q.rotation.transpose() * (A.vertices[i] - q.translation);
      q.outcodes_a[i] = outcode(q.va_in_b[i], lower_b, upper_b);
    }
  };
  q.edges_a.clear();
  for (std::size_t e = 0; e < A.edges.size(); ++e) {
    const auto i = static_cast<std::size_t>(A.edges[e].first), j = static_cast<std::size_t>(A.edges[e].second);
    if (std::max(q.heights_a[i], q.heights_a[j]) < floor_a) continue;
    classify_a(i);
    classify_a(j);
    if (segment_meets_box_coded(q.va_in_b[i], q.va_in_b[j], q.outcodes_a[i], q.outcodes_a[j], lower_b, upper_b))
      q.edges_a.push_back(static_cast<int>(e));
  }
  q.outcodes_b.assign(q.vb.size(), unknown_outcode);
  auto classify_b = [&](std::size_t i) {
    if (q.outcodes_b[i] == unknown_outcode) q.outcodes_b[i] = outcode(q.vb[i], lower_a, upper_a);
  };
  q.edges_b.clear();
  for (std::size_t e = 0; e < B.edges.size(); ++e) {
    const auto i = static_cast<std::size_t>(B.edges[e].first), j = static_cast<std::size_t>(B.edges[e].second);
    if (std::min(q.heights_b[i], q.heights_b[j]) > ceiling_b) continue;
    classify_b(i);
    classify_b(j);
    if (segment_meets_box_coded(q.vb[i], q.vb[j], q.outcodes_b[i], q.outcodes_b[j], lower_a, upper_a))
      q.edges_b.push_back(static_cast<int>(e));
  }
}

/// The cross products of an edge of A and an edge of B that form a face of the Minkowski
/// difference (their arcs cross on the Gauss map, Gregorius 2013) as candidates.
void search_edge_pairs(PolyhedronPair& q, const Witnesses& w, double touching, double size, BestPlane& best) {
  const ConvexPolyhedron& A = *q.A;
  const ConvexPolyhedron& B = *q.B;
  edges_within_reach(q, best.normal, std::max(-best.value, touching) + 1e-12 * size);
  // The arcs of B's edges on the Gauss map of -B (the Minkowski difference is A + (-B)).
  q.arcs_b.resize(q.edges_b.size());
  for (std::size_t k = 0; k < q.edges_b.size(); ++k) {
    const auto [left, right] = B.edge_faces[static_cast<std::size_t>(q.edges_b[k])];
    const Vec3 c1 = -q.nb[static_cast<std::size_t>(left)];
    const Vec3 c2 = -q.nb[static_cast<std::size_t>(right)];
    q.arcs_b[k] = {c1, c2, c2.cross(c1)};
  }
  for (int ea : q.edges_a) {
    const auto [ia, ja] = A.edges[static_cast<std::size_t>(ea)];
    const auto [left_a, right_a] = A.edge_faces[static_cast<std::size_t>(ea)];
    const Vec3& a1 = A.face_normals[static_cast<std::size_t>(left_a)];
    const Vec3& a2 = A.face_normals[static_cast<std::size_t>(right_a)];
    const Vec3 a2_x_a1 = a2.cross(a1);
    const Vec3& pa0 = A.vertices[static_cast<std::size_t>(ia)];
    const Vec3 edge_a = A.vertices[static_cast<std::size_t>(ja)] - pa0;
    for (std::size_t k = 0; k < q.edges_b.size(); ++k) {
      const auto& arc = q.arcs_b[k];
      if (!arcs_cross(a1, a2, a2_x_a1, arc[0], arc[1], arc[2])) continue;
      const auto [ib, jb] = B.edges[static_cast<std::size_t>(q.edges_b[k])];
      const Vec3& pb0 = q.vb[static_cast<std::size_t>(ib)];
      const Vec3 edge_b = q.vb[static_cast<std::size_t>(jb)] - pb0;
      Vec3 n = edge_a.cross(edge_b);
      const double length2 = n.squaredNorm();
      if (length2 <= 1e-20 * edge_a.squaredNorm() * edge_b.squaredNorm()) continue;  // parallel: a face case
      n /= std::sqrt(length2);
      if (n.dot(a1 + a2) < 0.0) n = -n;  // outward from A at edge A
      // Exact for a polytope (the edges are the supports); confirmed with the full supports so
      // slightly non-planar merged faces can never report more separation than there is.
      if (n.dot(pb0 - pa0) <= best.value) continue;
      if (witness_min_b(q, w, n) - witness_max_a(q, w, n) <= best.value) continue;
      const double value = separation(q, n);
      if (value > best.value) best = {value, n, CommonPlaneSource::edge_edge};
    }
  }
}

/// The witnesses: the supports along the warm-start normal and the vertices of GJK's last simplex.
Witnesses gather_witnesses(int support_a, int support_b, const GjkResult& gjk) {
  Witnesses w;
  w.a[0] = support_a;
  w.b[0] = support_b;
  w.count = 1;
  for (int k = 0; k < gjk.count; ++k) {
    w.a[static_cast<std::size_t>(w.count)] = gjk.simplex[static_cast<std::size_t>(k)].ia;
    w.b[static_cast<std::size_t>(w.count)] = gjk.simplex[static_cast<std::size_t>(k)].ib;
    ++w.count;
  }
  return w;
}

/// Asks the memory system for every cache line of `values` without waiting for them.
template <class T>
void prefetch(const std::vector<T>& values) {
  const auto* first = reinterpret_cast<const char*>(values.data());
  const auto* last = first + values.size() * sizeof(T);
  for (const char* line = first; line < last; line += 64) __builtin_prefetch(line);
}

/// The face arrays that the search and the contact points read, requested at once for both
/// bodies: in a large scene a pair's shapes are rarely in cache, and these arrays read one after
/// the other would each wait for memory in turn; requested together their waits overlap (and
/// overlap GJK, which reads only the vertices).
void prefetch_faces(const ConvexPolyhedron& shape) {
  prefetch(shape.face_normals);
  prefetch(shape.face_offsets);
}

/// The vertex graph, read last (by the contact points' ridges): requested after GJK, once the face
/// arrays' requests have been served (a hundred lines requested at once outrun the core's
/// outstanding-miss buffers).
void prefetch_vertex_graph(const ConvexPolyhedron& shape) {
  prefetch(shape.vertex_neighbours.offsets);
  prefetch(shape.vertex_neighbours.indices);
}

/// The edge arrays, read only by the separating-axis search (overlapping or touching pairs).
void prefetch_edges(const ConvexPolyhedron& shape) {
  prefetch(shape.edges);
  prefetch(shape.edge_faces);
}

/// The warm-start normal in A's frame: last step's plane, else the line of centres.
Vec3 initial_normal_in_a(const Mat3& rotation_a, const Vec3* initial_normal, const Vec3& translation) {
  if (initial_normal != nullptr && initial_normal->allFinite() && initial_normal->squaredNorm() > 0.0) {
    return (rotation_a.transpose() * *initial_normal).normalized();
  }
  if (translation.squaredNorm() > 0.0) return translation.normalized();
  return Vec3::UnitZ();
}

}  // namespace

void place_pair(const PolyhedronInWorld& pa, const PolyhedronInWorld& pb, PolyhedronPair& pair) {
  pair.A = pa.shape;
  pair.B = pb.shape;
  pair.rotation_a = pa.rotation;
  pair.position_a = pa.position;
  // Everything is done in A's body frame: A's data is used as stored, B is moved into it.
  pair.rotation = pa.rotation.transpose() * pb.rotation;
  pair.translation = pa.rotation.transpose() * (pb.position - pa.position);
}

namespace {

/// B's vertices into A's frame (pair.vb).
void move_b_vertices(PolyhedronPair& q) {
  const ConvexPolyhedron& B = *q.B;
  q.vb.resize(B.vertices.size());
  for (std::size_t i = 0; i < q.vb.size(); ++i) q.vb[i] = q.rotation * B.vertices[i] + q.translation;
}

/// B's face normals into A's frame (pair.nb).
void move_b_normals(PolyhedronPair& q) {
  const ConvexPolyhedron& B = *q.B;
  q.nb.resize(B.face_normals.size());
  for (std::size_t f = 0; f < q.nb.size(); ++f) q.nb[f] = q.rotation * B.face_normals[f];
}

}  // namespace

CommonPlane find_common_plane(const PolyhedronInWorld& pa, const PolyhedronInWorld& pb, const Vec3* initial_normal,
                              double cutoff) {
  PolyhedronPair pair;
  place_pair(pa, pb, pair);
  return find_common_plane(pair, initial_normal, cutoff);
}

CommonPlane find_common_plane(PolyhedronPair& q, const Vec3* initial_normal, double cutoff) {
  const ConvexPolyhedron& A = *q.A;
  const ConvexPolyhedron& B = *q.B;
  const double size = std::min(A.bounding_radius, B.bounding_radius);
  CommonPlane result;

  // --- 1. the warm-start normal; f(n0) with B's support taken in B's own frame: no need to move B yet ---
  const Vec3 n0 = initial_normal_in_a(q.rotation_a, initial_normal, q.translation);
  int support_a = 0, support_b = 0;
  const double f0 = min_dot(B.vertices, q.rotation.transpose() * n0, &support_b) + n0.dot(q.translation) -
                    max_dot(A.vertices, n0, &support_a);
  if (f0 >= cutoff) {
    result.normal = q.rotation_a * n0;
    result.gap = f0;
    result.complete = false;
    return result;
  }
  prefetch_faces(A);
  prefetch_faces(B);
  // B's vertices now, its face normals after GJK: by then their prefetch has arrived.
  move_b_vertices(q);
  BestPlane best{f0, n0, CommonPlaneSource::warm_start};

  // --- 2. apart? GJK gives the exact distance and closest-points direction ---
  const GjkResult gjk = gjk_distance(A.vertices, q.vb, n0, size);
  move_b_normals(q);
  prefetch_vertex_graph(A);
  prefetch_vertex_graph(B);
  // Below this distance GJK's closest-points direction is round-off (flush faces a hair apart
  // give a normal tilted by 1e-5 and a gap off by 1e-5 of the size): touching bodies go through
  // the separating-axis search as well, which finds the face normal exactly.
  const double touching = 1e-6 * size;
  if (gjk.separated) {
    const Vec3 n = gjk.closest.normalized();
    const double value = separation(q, n);
    if (value >= best.value) best = {value, n, CommonPlaneSource::closest_points};
  }
  if (!gjk.separated || gjk.closest.norm() < touching) {
    // --- 3. overlapping (or touching): separating-axis search for the least penetration ---
    // Every candidate value is <= touching here, so a candidate s that beats the best has
    // |s| < max(-best, touching).
    if (!gjk.separated) best.value = std::min(best.value, 0.0);
    prefetch_edges(A);
    prefetch_edges(B);
    const Witnesses witnesses = gather_witnesses(support_a, support_b, gjk);
    search_face_normals(q, witnesses, best);
    search_edge_pairs(q, witnesses, touching, size, best);
  }
  // --- 4. temporal coherence: keep last step's plane when it is as good as the optimum ---
  if (initial_normal != nullptr && best.source != CommonPlaneSource::warm_start && f0 >= best.value - 1e-9 * size) {
    best = {f0, n0, CommonPlaneSource::warm_start};
  }
  result.normal = q.rotation_a * best.normal;
  result.gap = best.value;
  result.source = best.source;
  return result;
}

}  // namespace rubble
