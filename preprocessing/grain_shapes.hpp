#pragma once
// Turning a packed grain (a centre and a radius, packing.hpp) into a polyhedral grain: a random
// convex polyhedron whose circumscribed sphere is the packed ball, at a random orientation.
//
// The placement snag: random_polyhedron.hpp rescales a polyhedron so that its smallest enclosing
// sphere has the requested diameter, but the body frame's origin is the centroid, which is not
// that sphere's centre. A grain placed by its centroid at the packed centre could stick out of
// its cell; placed by the centre of its enclosing sphere it stays inside the packed ball, hence
// inside its cell, at any orientation.
#include <cstdint>
#include <random>
#include <vector>

#include "core/math.hpp"
#include "core/shapes.hpp"
#include "preprocessing/packing.hpp"
#include "preprocessing/random_polyhedron.hpp"

namespace rubble {

/// A ball: centre and radius.
struct EnclosingSphere {
  Vec3 center = Vec3::Zero();  ///< m
  double radius = 0.0;         ///< m
};

/// The smallest ball containing every point (Welzl 1991, "Smallest enclosing disks (balls and
/// ellipsoids)", move-to-front variant; expected O(n)). The radius returned is the largest
/// distance from the centre to a point, so every point is inside up to round-off-free
/// comparison. Throws std::invalid_argument for an empty set.
EnclosingSphere minimal_enclosing_sphere(const std::vector<Vec3>& points);

/// A rotation uniformly distributed over SO(3) from three uniform draws (Shoemake 1992,
/// "Uniform random rotations", Graphics Gems III).
Quat random_rotation(std::mt19937_64& rng);

/// A polyhedral grain ready to add to a model: shape in its principal body frame, centroid
/// position and orientation in the world.
struct PlacedPolyhedron {
  ConvexPolyhedron shape;               ///< body frame (centroid at the origin)
  Vec3 position = Vec3::Zero();         ///< m, centroid in the world
  Quat orientation = Quat::Identity();  ///< body -> world
};

/// A random polyhedron (options.diameter is replaced by 2 grain.radius) at a random orientation,
/// placed so that its smallest enclosing sphere is centred on grain.position: every vertex lies
/// within grain.radius of grain.position. Everything is drawn from `seed` (one polyhedron seed,
/// three numbers for the orientation), so grains can be made in any order or in parallel.
PlacedPolyhedron random_polyhedron_in_ball(const PackedGrain& grain, RandomPolyhedronOptions options,
                                           std::uint64_t seed);

}  // namespace rubble
