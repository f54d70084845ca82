#pragma once
// Hand-built shapes and models shared by the postprocessing tests.
#include <cmath>
#include <utility>

#include "core/model.hpp"

namespace rubble::test {

/// An axis-aligned box polyhedron with the given half extents, faces counter-clockwise seen from
/// outside (vertex i has x = +hx if bit 0 is set, y = +hy if bit 1, z = +hz if bit 2).
inline ConvexPolyhedron box_polyhedron(const Vec3& h) {
  ConvexPolyhedron shape;
  for (int i = 0; i < 8; ++i) {
    shape.vertices.emplace_back((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(), (i & 4) ? h.z() : -h.z());
  }
  shape.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}};
  shape.face_normals = {-Vec3::UnitZ(), Vec3::UnitZ(), -Vec3::UnitX(), Vec3::UnitX(), -Vec3::UnitY(), Vec3::UnitY()};
  for (const auto& face : shape.faces) {
    for (std::size_t k = 0; k < face.size(); ++k) {
      const int a = face[k], b = face[(k + 1) % face.size()];
      if (a < b) shape.edges.emplace_back(a, b);
    }
  }
  return shape;
}

/// Volume of the box polyhedron.
inline double box_volume(const Vec3& h) { return 8.0 * h.x() * h.y() * h.z(); }

/// Principal inertia per unit density of the box: V/3 (hy^2 + hz^2, hx^2 + hz^2, hx^2 + hy^2).
inline Vec3 box_inertia_per_density(const Vec3& h) {
  const double v = box_volume(h);
  return v / 3.0 * Vec3(h.y() * h.y() + h.z() * h.z(), h.x() * h.x() + h.z() * h.z(), h.x() * h.x() + h.y() * h.y());
}

/// A regular tetrahedron with circumradius r, centroid at the origin (inertia not principal-exact
/// but isotropic: a regular tetrahedron's inertia tensor is a multiple of the identity).
inline ConvexPolyhedron tetrahedron(double r) {
  ConvexPolyhedron shape;
  const double s = r / std::sqrt(3.0);
  shape.vertices = {Vec3(s, s, s), Vec3(s, -s, -s), Vec3(-s, s, -s), Vec3(-s, -s, s)};
  // Each face omits one vertex; reversed where needed so that it is counter-clockwise from outside
  // (its normal points away from the centroid, which is the origin).
  shape.faces = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  for (const std::span<int> face : shape.faces) {
    Vec3 n = (shape.vertices[face[1]] - shape.vertices[face[0]])
                 .cross(shape.vertices[face[2]] - shape.vertices[face[0]])
                 .normalized();
    if (n.dot(shape.vertices[face[0]]) < 0.0) {
      std::swap(face[1], face[2]);
      n = -n;
    }
    shape.face_normals.push_back(n);
  }
  shape.edges = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  return shape;
}

/// Volume of the regular tetrahedron of circumradius r: edge a = r sqrt(8/3), V = a^3 / (6 sqrt 2).
inline double tetrahedron_volume(double r) {
  const double a = r * std::sqrt(8.0 / 3.0);
  return a * a * a / (6.0 * std::sqrt(2.0));
}

}  // namespace rubble::test
