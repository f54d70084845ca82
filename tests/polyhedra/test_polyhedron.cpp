// core/polyhedron: mass properties against closed forms, body frame, topology, bad meshes.
#include "core/polyhedron.hpp"

#include "core/input_error.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace rubble {
namespace {

struct Mesh {
  std::vector<Vec3> vertices;
  std::vector<std::vector<int>> faces;
};

Mesh box_mesh(double a, double b, double c) {
  Mesh m;
  for (int k = 0; k < 8; ++k) {
    m.vertices.emplace_back((k & 1) ? a / 2 : -a / 2, (k & 2) ? b / 2 : -b / 2, (k & 4) ? c / 2 : -c / 2);
  }
  m.faces = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  return m;
}

/// Regular tetrahedron of edge a (alternate corners of a cube of side a/sqrt(2)).
Mesh tetrahedron_mesh(double a) {
  const double h = a / std::sqrt(2.0) / 2.0;
  Mesh m;
  m.vertices = {{h, h, h}, {h, -h, -h}, {-h, h, -h}, {-h, -h, h}};
  m.faces = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
  return m;
}

/// Regular octahedron of edge a.
Mesh octahedron_mesh(double a) {
  const double r = a / std::sqrt(2.0);
  Mesh m;
  m.vertices = {{r, 0, 0}, {-r, 0, 0}, {0, r, 0}, {0, -r, 0}, {0, 0, r}, {0, 0, -r}};
  m.faces = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  return m;
}

Mesh moved(Mesh m, const Vec3& shift, const Quat& rotation) {
  for (Vec3& v : m.vertices) v = rotation * v + shift;
  return m;
}

/// Whether `value` is within a relative `tolerance` of `reference` (for EXPECT_TRUE).
::testing::AssertionResult near_relative(double value, double reference, double tolerance = 1e-12) {
  if (std::abs(value - reference) <= tolerance * std::abs(reference)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "value " << value << " reference " << reference << " (relative tolerance "
                                       << tolerance << ")";
}

// Reference: V = a^3, I = V a^2 / 6 (per unit density) about any axis through the centre.
TEST(PolyhedronMass, CubeMatchesClosedForm) {
  const double a = 0.7;
  const Mesh m = moved(box_mesh(a, a, a), Vec3(3, -2, 5), Quat(Eigen::AngleAxisd(0.3, Vec3(1, 2, 3).normalized())));
  const PolyhedronMassProperties p = polyhedron_mass_properties(m.vertices, m.faces);
  EXPECT_TRUE(near_relative(p.volume, a * a * a));
  EXPECT_NEAR((p.centroid - Vec3(3, -2, 5)).norm(), 0.0, 1e-12 * 5);
  const double inertia = a * a * a * a * a / 6.0;
  EXPECT_NEAR((p.inertia_per_density - inertia * Mat3::Identity()).norm(), 0.0, 1e-12 * inertia);
}

// Reference: I_x = V (b^2 + c^2) / 12 and cyclic.
TEST(PolyhedronMass, BoxMatchesClosedForm) {
  const double a = 1.0, b = 0.6, c = 0.3;
  const Quat rotation(Eigen::AngleAxisd(1.1, Vec3(-1, 0.5, 2).normalized()));
  const Mesh m = moved(box_mesh(a, b, c), Vec3(-1, 4, 2), rotation);
  const ConvexPolyhedron shape = make_convex_polyhedron(m.vertices, m.faces);
  const double volume = a * b * c;
  EXPECT_TRUE(near_relative(shape.volume, volume));
  // Principal axes come out sorted by increasing moment: x (long) first.
  const Vec3 expected(volume * (b * b + c * c) / 12, volume * (a * a + c * c) / 12, volume * (a * a + b * b) / 12);
  for (int k = 0; k < 3; ++k) EXPECT_TRUE(near_relative(shape.principal_inertia_per_density[k], expected[k]));
}

// Reference: V = a^3 / (6 sqrt 2), I = V a^2 / 20 about any axis through the centre.
TEST(PolyhedronMass, RegularTetrahedronMatchesClosedForm) {
  const double a = 1.3;
  const Mesh m = moved(tetrahedron_mesh(a), Vec3(0.1, 0.2, 0.3), Quat(Eigen::AngleAxisd(0.8, Vec3::UnitY())));
  const PolyhedronMassProperties p = polyhedron_mass_properties(m.vertices, m.faces);
  const double volume = a * a * a / (6.0 * std::sqrt(2.0));
  EXPECT_TRUE(near_relative(p.volume, volume));
  EXPECT_NEAR((p.inertia_per_density - volume * a * a / 20.0 * Mat3::Identity()).norm(), 0.0, 1e-12 * volume * a * a);
}

// Reference: V = sqrt(2)/3 a^3, I = V a^2 / 10 about any axis through the centre.
TEST(PolyhedronMass, RegularOctahedronMatchesClosedForm) {
  const double a = 0.9;
  const Mesh m = moved(octahedron_mesh(a), Vec3(7, 7, -7), Quat(Eigen::AngleAxisd(2.0, Vec3(1, 1, 0).normalized())));
  const PolyhedronMassProperties p = polyhedron_mass_properties(m.vertices, m.faces);
  const double volume = std::sqrt(2.0) / 3.0 * a * a * a;
  EXPECT_TRUE(near_relative(p.volume, volume));
  EXPECT_NEAR((p.inertia_per_density - volume * a * a / 10.0 * Mat3::Identity()).norm(), 0.0, 1e-12 * volume * a * a);
}

TEST(PolyhedronBuild, BodyFrameIsCentroidAndPrincipalAxesAndPoseMapsBack) {
  const Quat rotation(Eigen::AngleAxisd(0.7, Vec3(0.2, -1, 0.4).normalized()));
  const Vec3 shift(2, 3, -1);
  const Mesh m = moved(box_mesh(1.0, 0.5, 0.2), shift, rotation);
  PolyhedronPose pose;
  const ConvexPolyhedron shape = make_convex_polyhedron(m.vertices, m.faces, {}, &pose);
  EXPECT_NEAR((pose.centroid - shift).norm(), 0.0, 1e-12);
  // Every body vertex maps back onto an input vertex (same order).
  for (std::size_t i = 0; i < shape.vertices.size(); ++i) {
    EXPECT_NEAR((pose.centroid + pose.orientation * shape.vertices[i] - m.vertices[i]).norm(), 0.0, 1e-12);
  }
  // Centroid at the origin and a diagonal inertia in the body frame.
  const PolyhedronMassProperties body = polyhedron_mass_properties(shape.vertices, shape.faces);
  EXPECT_NEAR(body.centroid.norm(), 0.0, 1e-12);
  const Mat3 off = body.inertia_per_density - Mat3(body.inertia_per_density.diagonal().asDiagonal());
  EXPECT_LT(off.norm(), 1e-12 * body.inertia_per_density.norm());
}

TEST(PolyhedronBuild, AxisAlignedCubeKeepsItsAxes) {
  const Mesh m = box_mesh(1, 1, 1);
  PolyhedronPose pose;
  const ConvexPolyhedron shape = make_convex_polyhedron(m.vertices, m.faces, {}, &pose);
  EXPECT_NEAR(pose.orientation.angularDistance(Quat::Identity()), 0.0, 1e-14);
  EXPECT_NEAR(shape.face_normals[0].x(), -1.0, 1e-15);  // face {0,4,6,2} is x = -a/2
}

TEST(PolyhedronBuild, TopologyOfACube) {
  const Mesh m = box_mesh(2, 2, 2);
  const ConvexPolyhedron shape = make_convex_polyhedron(m.vertices, m.faces);
  EXPECT_EQ(shape.edges.size(), 12u);
  ASSERT_EQ(shape.edge_faces.size(), 12u);
  for (std::size_t e = 0; e < 12; ++e) {
    const auto [i, j] = shape.edges[e];
    EXPECT_LT(i, j);
    // Both faces hold the edge, the left one in the direction i -> j.
    const auto [left, right] = shape.edge_faces[e];
    EXPECT_NE(left, right);
    const auto& lf = shape.faces[static_cast<std::size_t>(left)];
    bool found = false;
    for (std::size_t k = 0; k < lf.size(); ++k) found |= lf[k] == i && lf[(k + 1) % lf.size()] == j;
    EXPECT_TRUE(found);
    // The two face normals are perpendicular for a cube.
    EXPECT_NEAR(
        shape.face_normals[static_cast<std::size_t>(left)].dot(shape.face_normals[static_cast<std::size_t>(right)]),
        0.0, 1e-15);
  }
  for (const auto& neighbours : shape.vertex_neighbours) EXPECT_EQ(neighbours.size(), 3u);
  for (std::size_t f = 0; f < 6; ++f) EXPECT_NEAR(shape.face_offsets[f], 1.0, 1e-15);
  EXPECT_NEAR(shape.bounding_radius, std::sqrt(3.0), 1e-15);
  EXPECT_EQ(support_vertex(shape, Vec3(1, 1, 1)), 7);
  EXPECT_NEAR(support_value(shape, Vec3(0, 0, -1)), 1.0, 1e-15);
}

TEST(PolyhedronBuild, ScalingScalesVolumeAndInertia) {
  const Mesh m = tetrahedron_mesh(1.0);
  const ConvexPolyhedron shape = make_convex_polyhedron(m.vertices, m.faces);
  const ConvexPolyhedron twice = scaled_polyhedron(shape, 2.0);
  EXPECT_TRUE(near_relative(twice.volume, 8.0 * shape.volume));
  EXPECT_TRUE(near_relative(twice.principal_inertia_per_density.x(), 32.0 * shape.principal_inertia_per_density.x()));
  EXPECT_TRUE(near_relative(twice.bounding_radius, 2.0 * shape.bounding_radius));
}

TEST(PolyhedronBuild, BoxPolyhedronHasTheBoxVolume) {
  const ConvexPolyhedron box = make_box_polyhedron(Vec3(1, 2, 3));
  EXPECT_TRUE(near_relative(box.volume, 48.0));
  EXPECT_EQ(box.faces.size(), 6u);
}

TEST(PolyhedronBuild, AddPolyhedronGrainUsesTheShapeMass) {
  Model model;
  model.materials.push_back({"rock", 2000.0});
  const Mesh m = box_mesh(1, 1, 1);
  const int id = add_polyhedron_grain(model, make_convex_polyhedron(m.vertices, m.faces), 0);
  EXPECT_TRUE(near_relative(model.mass[static_cast<std::size_t>(id)], 2000.0));
  EXPECT_TRUE(near_relative(model.principal_inertia[static_cast<std::size_t>(id)].x(), 2000.0 / 6.0));
}

// --- bad meshes: a clear error, never a crash ---

/// Whether building `m` throws a PolyhedronError whose message holds `fragment` (for EXPECT_TRUE).
::testing::AssertionResult rejected_with(const Mesh& m, const std::string& fragment) {
  try {
    (void)make_convex_polyhedron(m.vertices, m.faces);
  } catch (const PolyhedronError& e) {
    if (std::string(e.what()).find(fragment) != std::string::npos) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "message \"" << e.what() << "\" lacks \"" << fragment << "\"";
  }
  return ::testing::AssertionFailure() << "no error, expected one containing \"" << fragment << "\"";
}

// The command line maps every InputError to exit code 2 by the base (docs/exit-codes.md): a bad
// mesh is one, and still says which face is at fault.
TEST(PolyhedronBuild, BadMeshIsAnInputErrorNamingTheFace) {
  Mesh open = box_mesh(1, 1, 1);
  open.faces.pop_back();
  try {
    (void)make_convex_polyhedron(open.vertices, open.faces);
    ADD_FAILURE() << "no error for an open mesh";
  } catch (const InputError& e) {
    const auto* error = dynamic_cast<const PolyhedronError*>(&e);
    ASSERT_NE(error, nullptr) << e.what();
    EXPECT_GE(error->face, 0) << e.what();
    EXPECT_LT(error->face, static_cast<int>(open.faces.size())) << e.what();
  }
}

TEST(PolyhedronBuild, RejectsBadMeshes) {
  Mesh open = box_mesh(1, 1, 1);
  open.faces.pop_back();
  EXPECT_TRUE(rejected_with(open, "not closed"));

  Mesh flipped = box_mesh(1, 1, 1);
  std::reverse(flipped.faces[2].begin(), flipped.faces[2].end());
  EXPECT_TRUE(rejected_with(flipped, "same direction"));

  Mesh clockwise = box_mesh(1, 1, 1);
  for (auto& f : clockwise.faces) std::reverse(f.begin(), f.end());
  EXPECT_TRUE(rejected_with(clockwise, "clockwise"));

  Mesh dented = box_mesh(1, 1, 1);
  dented.vertices[7] *= 0.5;  // a corner pushed in: faces no longer planar / convex
  EXPECT_TRUE(rejected_with(dented, "face"));

  Mesh out_of_range = box_mesh(1, 1, 1);
  out_of_range.faces[0][1] = 12;
  EXPECT_TRUE(rejected_with(out_of_range, "uses vertex 12"));

  Mesh flat;
  flat.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  flat.faces = {{0, 1, 3, 2}, {0, 2, 3, 1}};
  EXPECT_TRUE(rejected_with(flat, "at least 4 faces"));

  Mesh lonely = box_mesh(1, 1, 1);
  lonely.vertices.emplace_back(5, 5, 5);
  EXPECT_TRUE(rejected_with(lonely, "vertex 8 is on no face"));
}

/// A triangulated UV sphere of radius r: n_lat rings of n_lon vertices and the two poles.
Mesh uv_sphere_mesh(int n_lat, int n_lon, double r) {
  Mesh m;
  m.vertices.emplace_back(0, 0, r);
  for (int i = 1; i <= n_lat; ++i) {
    const double t = M_PI * i / (n_lat + 1);
    for (int j = 0; j < n_lon; ++j) {
      const double p = 2 * M_PI * j / n_lon;
      m.vertices.emplace_back(r * std::sin(t) * std::cos(p), r * std::sin(t) * std::sin(p), r * std::cos(t));
    }
  }
  m.vertices.emplace_back(0, 0, -r);
  const auto at = [&](int i, int j) { return 1 + (i - 1) * n_lon + (j % n_lon); };
  const int last = static_cast<int>(m.vertices.size()) - 1;
  for (int j = 0; j < n_lon; ++j) m.faces.push_back({0, at(1, j), at(1, j + 1)});
  for (int i = 1; i < n_lat; ++i) {
    for (int j = 0; j < n_lon; ++j) {
      m.faces.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      m.faces.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  for (int j = 0; j < n_lon; ++j) m.faces.push_back({last, at(n_lat, j + 1), at(n_lat, j)});
  return m;
}

// Meshes of >= 256 vertices are checked on CGAL's hull (each face's highest vertex found by an
// uphill walk) instead of against every vertex: the supporting-plane offsets must be the maxima
// over all vertices, as a brute-force scan finds them, and a vertex bumped out or dented in by 1%
// of the radius must still be caught.
TEST(PolyhedronBuild, LargeMeshesAreCheckedOnTheHull) {
  const Mesh sphere = uv_sphere_mesh(30, 30, 2.0);  // 902 vertices, 1800 triangles
  const ConvexPolyhedron shape = make_convex_polyhedron(sphere.vertices, sphere.faces);
  ASSERT_EQ(shape.faces.size(), 1800u);
  for (std::size_t f = 0; f < shape.faces.size(); ++f) {
    double highest = -1e300;
    for (const Vec3& v : shape.vertices) highest = std::max(highest, shape.face_normals[f].dot(v));
    EXPECT_NEAR(shape.face_offsets[f], highest, 1e-14 * 2.0) << "face " << f;
  }

  Mesh bumped = sphere;
  bumped.vertices[400] *= 1.01;
  EXPECT_TRUE(rejected_with(bumped, "not convex"));
  Mesh dented = sphere;
  dented.vertices[400] *= 0.99;
  EXPECT_TRUE(rejected_with(dented, "not convex"));
}

}  // namespace
}  // namespace rubble
