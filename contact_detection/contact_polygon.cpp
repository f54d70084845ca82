#include "contact_detection/contact_polygon.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <utility>

namespace rubble::contact_polygon {

Polygon hull_2d(Polygon points, double tolerance) {
  Polygon hull;
  HullBuffers buffers;
  hull_2d(points, tolerance, hull, buffers);
  return hull;
}

namespace {

/// The order of Andrew's monotone chain: by x, then y, then vertex id (deterministic on ties).
bool chain_order(const CapVertex& a, const CapVertex& b) {
  return a.p.x() < b.p.x() ||
         (a.p.x() == b.p.x() && (a.p.y() < b.p.y() || (a.p.y() == b.p.y() && a.vertex < b.vertex)));
}

/// Andrew's monotone chain over `unique[0, count)` (sorted by chain_order, no coincident points,
/// count >= 3) into `hull` (room for 2 count points): the hull's size, counter-clockwise. A turn
/// counts only when left by more than `tolerance` (the distance of the third point from the line
/// of the first two). Shared by hull_2d and quad_hull_area so that both give the same bits.
template <class Points, class Hull>
std::size_t monotone_chain(const Points& unique, std::size_t count, double tolerance, Hull& hull) {
  std::size_t k = 0;
  auto turn = [&](const CapVertex& o, const CapVertex& a, const CapVertex& b) {
    const Vec2 oa = a.p - o.p;
    const Vec2 ob = b.p - o.p;
    return cross2(oa, ob) > tolerance * oa.norm();
  };
  for (std::size_t i = 0; i < count; ++i) {
    while (k >= 2 && !turn(hull[k - 2], hull[k - 1], unique[i])) --k;
    hull[k++] = unique[i];
  }
  for (std::size_t i = count - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && !turn(hull[k - 2], hull[k - 1], unique[i])) --k;
    hull[k++] = unique[i];
  }
  return k - 1;
}

}  // namespace

void hull_2d(Polygon& points, double tolerance, Polygon& hull, HullBuffers& buffers) {
  std::sort(points.begin(), points.end(), chain_order);
  // Merge coincident points (keep the lowest vertex id for determinism).
  Polygon& unique = buffers.unique;
  unique.clear();
  const double tolerance2 = tolerance * tolerance;
  for (const CapVertex& c : points) {
    bool found = false;
    for (CapVertex& u : unique) {
      if ((u.p - c.p).squaredNorm() <= tolerance2) {
        found = true;
        u.vertex = std::min(u.vertex, c.vertex);
        break;
      }
    }
    if (!found) unique.push_back(c);
  }
  if (unique.size() <= 2) {
    hull.assign(unique.begin(), unique.end());
    return;
  }
  hull.resize(2 * unique.size());
  hull.resize(monotone_chain(unique, unique.size(), tolerance, hull));
  if (hull.size() < 2) hull.assign(1, unique.front());
}

Vec2 closest_on_boundary(const Polygon& polygon, const Vec2& q, std::size_t vertex_count, std::uint32_t& feature) {
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

Vec2 clamp_into(const Polygon& polygon, const Vec2& q) {
  if (polygon.size() >= 3 && inside(polygon, q, 0.0)) return q;
  std::uint32_t feature = 0;
  return closest_on_boundary(polygon, q, 0, feature);
}

namespace {

/// The area of the convex hull of `points` (sorted in place), with caller-owned buffers.
double polygon_area(Polygon& points, Polygon& hull, HullBuffers& buffers) {
  hull_2d(points, 0.0, hull, buffers);
  double area = 0.0;
  for (std::size_t i = 0; i < hull.size() && hull.size() >= 3; ++i) {
    area += cross2(hull[i].p, hull[(i + 1) % hull.size()].p);
  }
  return 0.5 * std::abs(area);
}

/// The area of the convex hull of four points, on the stack: the same order, merge of coincident
/// points and chain as hull_2d with zero tolerance, then the same sum, so the same bits as
/// polygon_area (which reduce_to_four called once per candidate, with a vector sort and copies).
double quad_hull_area(std::array<CapVertex, 4> points) {
  std::sort(points.begin(), points.end(), chain_order);
  std::array<CapVertex, 4> unique;
  std::size_t count = 0;
  for (const CapVertex& c : points) {
    bool found = false;
    for (std::size_t k = 0; k < count; ++k) found = found || (unique[k].p - c.p).squaredNorm() <= 0.0;
    if (!found) unique[count++] = c;
  }
  if (count <= 2) return 0.0;
  std::array<CapVertex, 8> hull;
  const std::size_t size = monotone_chain(unique, count, 0.0, hull);
  if (size < 3) return 0.0;
  double area = 0.0;
  for (std::size_t i = 0; i < size; ++i) area += cross2(hull[i].p, hull[(i + 1) % size].p);
  return 0.5 * std::abs(area);
}

}  // namespace

double polygon_area(Polygon points) {
  Polygon hull;
  HullBuffers buffers;
  return polygon_area(points, hull, buffers);
}

std::vector<Candidate> reduce_to_four(const std::vector<Candidate>& all, double area_tolerance) {
  std::vector<Candidate> kept;
  reduce_to_four(all, area_tolerance, kept);
  return kept;
}

void reduce_to_four(const std::vector<Candidate>& all, double area_tolerance, std::vector<Candidate>& kept) {
  if (all.size() <= 4) {
    kept.assign(all.begin(), all.end());
    return;
  }
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
  kept.assign({all[i1], all[i2]});
  if (area3 <= area_tolerance) return;  // all collinear: a segment
  kept.push_back(all[i3]);
  const double triangle = 0.5 * area3;
  std::size_t i4 = all.size();
  double best_gain = area_tolerance;
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (i == i1 || i == i2 || i == i3) continue;
    const double gain = quad_hull_area({{{all[i1].p, 0}, {all[i2].p, 1}, {all[i3].p, 2}, {all[i].p, 3}}}) - triangle;
    if (gain > best_gain) {
      best_gain = gain;
      i4 = i;
    }
  }
  if (i4 < all.size()) kept.push_back(all[i4]);
}

std::vector<Candidate> add_off_plane_points(const std::vector<Candidate>& all, std::vector<Candidate> kept,
                                            double tolerance, std::size_t max_points) {
  ReductionBuffers buffers;
  add_off_plane_points(all, kept, tolerance, max_points, buffers);
  return kept;
}

void add_off_plane_points(const std::vector<Candidate>& all, std::vector<Candidate>& kept, double tolerance,
                          std::size_t max_points, ReductionBuffers& buffers) {
  if (kept.size() == all.size() || kept.size() >= max_points) return;
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
  auto& deficits = buffers.deficits;
  deficits.clear();
  const std::size_t kept_count = kept.size();
  for (std::size_t i = 0; i < all.size(); ++i) {
    bool is_kept = false;
    for (std::size_t k = 0; k < kept_count; ++k) is_kept = is_kept || (kept[k].p - all[i].p).squaredNorm() == 0.0;
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
}

}  // namespace rubble::contact_polygon
