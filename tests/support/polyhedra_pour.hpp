#pragma once
// The pour of random polyhedra used by tests/polyhedra (200 grains) and tests/stability (300):
// a box of plane walls and the grains in layers above its floor, in one line.
#include <cstdint>
#include <random>
#include <utility>

#include "core/polyhedron.hpp"
#include "preprocessing/random_polyhedron.hpp"
#include "support/test_scene.hpp"

namespace rubble::testing {

/// A floor and four plane walls (a 0.92 m square box), then `count` random polyhedra (10-20
/// vertices, circumscribed diameter `d`, shape k from seed first_shape_seed + k) one per cell of
/// a 7 x 7 grid of layers of pitch 1.25 d (more than the largest bounding diameter: no initial
/// overlap), each a bounding radius plus 1 cm above its layer's floor, with a random orientation
/// and a small random horizontal velocity (0.1 m/s scale) drawn from `seed`.
inline void add_polyhedra_pour(TestScene& s, int count, double d, std::uint64_t first_shape_seed, std::uint64_t seed) {
  const double half_width = 0.46;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  s.plane(Vec3(-half_width, 0, 0), Vec3::UnitX());
  s.plane(Vec3(half_width, 0, 0), -Vec3::UnitX());
  s.plane(Vec3(0, -half_width, 0), Vec3::UnitY());
  s.plane(Vec3(0, half_width, 0), -Vec3::UnitY());
  RandomPolyhedronOptions shape;
  shape.diameter = d;
  shape.min_vertices = 10;
  shape.max_vertices = 20;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  const double pitch = 1.25 * d;
  for (int k = 0; k < count; ++k) {
    const int layer = k / 49, i = k % 49 / 7, j = k % 7;
    ConvexPolyhedron p = generate_random_polyhedron(shape, first_shape_seed + static_cast<std::uint64_t>(k));
    const double r = p.bounding_radius;
    const int id = add_polyhedron_grain(s.model, std::move(p), 0);
    const Vec3 position((i - 3.0) * pitch, (j - 3.0) * pitch, r + 0.01 + layer * pitch);
    const Quat q = Quat(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
    s.place(id, position, q, 0.1 * Vec3(normal(rng), normal(rng), 0.0));
  }
}

}  // namespace rubble::testing
