#include "preprocessing/grain_shapes.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "core/polyhedron.hpp"

namespace rubble {
namespace {

/// The smallest ball with every point of `boundary` (1 to 4 points) on its surface; radius -1
/// for none. Degenerate sets (collinear triples, coplanar quadruples) fall back to the ball of a
/// subset, which the Welzl recursion then corrects if a point is left outside.
EnclosingSphere ball_through(const std::vector<Vec3>& boundary) {
  switch (boundary.size()) {
    case 0:
      return {Vec3::Zero(), -1.0};
    case 1:
      return {boundary[0], 0.0};
    case 2:
      return {0.5 * (boundary[0] + boundary[1]), 0.5 * (boundary[1] - boundary[0]).norm()};
    case 3: {
      // Circumcircle of a triangle in 3D: c = a + (|u|^2 (v x (u x v))... written with w = u x v:
      // c = a + (|u|^2 (v x w) + |v|^2 (w x u)) / (2 |w|^2), u = b - a, v = c - a.
      const Vec3& a = boundary[0];
      const Vec3 u = boundary[1] - a;
      const Vec3 v = boundary[2] - a;
      const Vec3 w = u.cross(v);
      const double w2 = w.squaredNorm();
      if (!(w2 > 1e-24 * u.squaredNorm() * v.squaredNorm())) {
        // Collinear: the ball of the farthest pair.
        const double duv = (boundary[2] - boundary[1]).squaredNorm();
        if (u.squaredNorm() >= v.squaredNorm() && u.squaredNorm() >= duv)
          return ball_through({boundary[0], boundary[1]});
        if (v.squaredNorm() >= duv) return ball_through({boundary[0], boundary[2]});
        return ball_through({boundary[1], boundary[2]});
      }
      const Vec3 offset = (u.squaredNorm() * v.cross(w) + v.squaredNorm() * w.cross(u)) / (2.0 * w2);
      return {a + offset, offset.norm()};
    }
    default: {
      // Circumsphere of a tetrahedron: 2 (p_i - a) . x = |p_i - a|^2, i = 1..3, x = centre - a.
      const Vec3& a = boundary[0];
      Mat3 m;
      Vec3 rhs;
      for (int i = 0; i < 3; ++i) {
        const Vec3 d = boundary[static_cast<std::size_t>(i) + 1] - a;
        m.row(i) = 2.0 * d.transpose();
        rhs[i] = d.squaredNorm();
      }
      const double scale = m.cwiseAbs().maxCoeff();
      if (!(std::abs(m.determinant()) > 1e-14 * scale * scale * scale)) {
        return ball_through({boundary[0], boundary[1], boundary[2]});
      }
      const Vec3 x = m.partialPivLu().solve(rhs);
      return {a + x, x.norm()};
    }
  }
}

bool inside(const EnclosingSphere& ball, const Vec3& p) {
  // Relative slack: points on the sphere (the boundary ones) must count as inside.
  return ball.radius >= 0.0 && (p - ball.center).norm() <= ball.radius * (1.0 + 1e-12) + 1e-300;
}

/// Welzl's recursion, move-to-front: the smallest ball of points[0, end) with `boundary` on its surface.
EnclosingSphere welzl(std::vector<Vec3>& points, std::size_t end, std::vector<Vec3>& boundary) {
  EnclosingSphere ball = ball_through(boundary);
  if (boundary.size() == 4) return ball;
  for (std::size_t i = 0; i < end; ++i) {
    if (inside(ball, points[i])) continue;
    boundary.push_back(points[i]);
    ball = welzl(points, i, boundary);
    boundary.pop_back();
    // Move to front: points that fell outside once are likely to define the final ball.
    std::rotate(points.begin(), points.begin() + static_cast<std::ptrdiff_t>(i),
                points.begin() + static_cast<std::ptrdiff_t>(i) + 1);
  }
  return ball;
}

}  // namespace

EnclosingSphere minimal_enclosing_sphere(const std::vector<Vec3>& points) {
  if (points.empty()) throw std::invalid_argument("minimal_enclosing_sphere: no points");
  std::vector<Vec3> work = points;
  std::vector<Vec3> boundary;
  boundary.reserve(4);
  EnclosingSphere ball = welzl(work, work.size(), boundary);
  // The radius that really encloses every point from this centre (round-off of the solves).
  ball.radius = 0.0;
  for (const Vec3& p : points) ball.radius = std::max(ball.radius, (p - ball.center).norm());
  return ball;
}

Quat random_rotation(std::mt19937_64& rng) {
  // Shoemake: q = (sqrt(1-u1) sin 2pi u2, sqrt(1-u1) cos 2pi u2, sqrt(u1) sin 2pi u3, sqrt(u1) cos 2pi u3).
  const double u1 = uniform_01(rng);
  const double u2 = uniform_01(rng);
  const double u3 = uniform_01(rng);
  const double two_pi = 2.0 * std::numbers::pi;
  const double a = std::sqrt(1.0 - u1);
  const double b = std::sqrt(u1);
  Quat q(b * std::cos(two_pi * u3), a * std::sin(two_pi * u2), a * std::cos(two_pi * u2), b * std::sin(two_pi * u3));
  q.normalize();
  return q;
}

PlacedPolyhedron random_polyhedron_in_ball(const PackedGrain& grain, RandomPolyhedronOptions options,
                                           std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const std::uint64_t shape_seed = rng();
  options.diameter = 2.0 * grain.radius;
  PlacedPolyhedron placed;
  placed.shape = generate_random_polyhedron(options, shape_seed);
  EnclosingSphere ball = minimal_enclosing_sphere(placed.shape.vertices);
  if (ball.radius > grain.radius) {
    // The generator's own enclosing sphere may differ from ours by round-off: shrink to fit.
    const double factor = grain.radius / ball.radius * (1.0 - 1e-12);
    placed.shape = scaled_polyhedron(placed.shape, factor);
    ball.center *= factor;
  }
  placed.orientation = random_rotation(rng);
  // Centroid = ball centre - R c, so that the enclosing sphere's centre lands on the packed centre.
  placed.position = grain.position - placed.orientation * ball.center;
  return placed;
}

}  // namespace rubble
