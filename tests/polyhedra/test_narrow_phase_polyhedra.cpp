// contact_detection/narrow_phase_polyhedra: contact points of polyhedra against polyhedra,
// spheres, planes and boxes, against hand-computed geometry.
#include "contact_detection/narrow_phase_polyhedra.hpp"
#include "contact_detection/common_plane.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "core/polyhedron.hpp"
#include "support/rotation.hpp"

namespace rubble {
namespace {

constexpr double alert = 0.01;

struct Scene {
  Model model;
  State state;
  Scene() {
    model.materials.push_back({"rock", 1000.0});
    model.contact_laws.reset(1, ContactLaw{});
  }
  std::uint32_t cube(double side, const Vec3& position, const Quat& orientation = Quat::Identity()) {
    const int id = add_polyhedron_grain(model, make_box_polyhedron(Vec3::Constant(side / 2)), 0);
    return place(id, position, orientation);
  }
  std::uint32_t sphere(double radius, const Vec3& position) {
    return place(add_sphere(model, radius, 0), position, Quat::Identity());
  }
  std::uint32_t plane(const Vec3& point, const Vec3& normal) {
    return place(add_plane_wall(model, normal, 0), point, Quat::Identity());
  }
  std::uint32_t box(const Vec3& half, const Vec3& position, const Quat& orientation = Quat::Identity()) {
    return place(add_box_wall(model, half, 0), position, orientation);
  }
  std::uint32_t place(int id, const Vec3& position, const Quat& orientation) {
    State grown;
    grown.resize(model.body_count());
    for (std::size_t i = 0; i < state.body_count(); ++i) {
      grown.position[i] = state.position[i];
      grown.orientation[i] = state.orientation[i];
    }
    state = grown;
    state.position[static_cast<std::size_t>(id)] = position;
    state.orientation[static_cast<std::size_t>(id)] = orientation;
    return static_cast<std::uint32_t>(id);
  }
  ContactList polyhedra(std::uint32_t a, std::uint32_t b, const Vec3* warm = nullptr) {
    ContactList contacts;
    Vec3 normal = Vec3::Zero();
    collide_polyhedron_polyhedron(model, state, a, b, alert, warm, contacts, normal);
    return contacts;
  }
};

void expect_normal(const ContactList& contacts, const Vec3& n) {
  for (const Contact& c : contacts) {
    EXPECT_NEAR((c.frame.col(0) - n).norm(), 0.0, 1e-12);
    EXPECT_NEAR((c.frame.transpose() * c.frame - Mat3::Identity()).norm(), 0.0, 1e-12);
  }
}

/// True when some contact point is within `tolerance` of p.
bool has_point(const ContactList& contacts, const Vec3& p, double tolerance = 1e-12) {
  for (const Contact& c : contacts) {
    if ((c.point - p).norm() <= tolerance) return true;
  }
  return false;
}

// Face-face: a unit cube on another, 1 mm overlap, shifted by (0.2, 0.3): the contact area is
// the 0.8 x 0.7 rectangle, whose 4 corners carry the contact (midway: z = 0.5 - 0.0005).
TEST(PolyhedronContacts, FaceFaceGivesTheFourCornersOfTheOverlap) {
  Scene s;
  const auto a = s.cube(1.0, Vec3::Zero());
  const auto b = s.cube(1.0, Vec3(0.2, 0.3, 0.999));
  const ContactList contacts = s.polyhedra(a, b);
  ASSERT_EQ(contacts.size(), 4u);
  expect_normal(contacts, Vec3::UnitZ());
  for (const Contact& c : contacts) EXPECT_NEAR(c.gap, -0.001, 1e-12);
  const double z = 0.5 - 0.0005;
  for (const Vec3& corner : {Vec3(-0.3, -0.2, z), Vec3(0.5, -0.2, z), Vec3(0.5, 0.5, z), Vec3(-0.3, 0.5, z)}) {
    EXPECT_TRUE(has_point(contacts, corner)) << corner.transpose();
  }
  for (std::size_t i = 0; i < contacts.size(); ++i) {
    EXPECT_EQ(contacts[i].id.body_a, a);
    EXPECT_EQ(contacts[i].id.body_b, b);
    for (std::size_t j = 0; j < i; ++j) EXPECT_NE(contacts[i].id, contacts[j].id);
  }
}

// A cube turned 45 degrees about z on another: the overlap is an octagon; 4 of its corners that
// span the largest area are kept, never 3 collinear.
TEST(PolyhedronContacts, OctagonIsReducedToFourPointsCarryingTheArea) {
  Scene s;
  const auto a = s.cube(1.0, Vec3::Zero());
  const auto b = s.cube(1.0, Vec3(0, 0, 0.999), Quat(Eigen::AngleAxisd(M_PI / 4, Vec3::UnitZ())));
  const ContactList contacts = s.polyhedra(a, b);
  ASSERT_EQ(contacts.size(), 4u);
  // The kept quadrilateral covers more than half of the octagon (area 2 (sqrt 2 - 1) ~ 0.83).
  std::vector<Vec3> p;
  for (const Contact& c : contacts) p.push_back(c.point);
  std::sort(p.begin(), p.end(),
            [](const Vec3& x, const Vec3& y) { return std::atan2(x.y(), x.x()) < std::atan2(y.y(), y.x()); });
  double area = 0.0;
  for (std::size_t i = 0; i < 4; ++i) area += 0.5 * (p[i].x() * p[(i + 1) % 4].y() - p[(i + 1) % 4].x() * p[i].y());
  EXPECT_GT(area, 0.5);
}

// Edge-face: a cube turned 45 degrees about x rests an edge on a face: 2 points, the ends of the
// edge (x = +-0.5), gap -0.001.
TEST(PolyhedronContacts, EdgeFaceGivesTwoPoints) {
  Scene s;
  const auto a = s.cube(2.0, Vec3::Zero());
  const double h = std::sqrt(0.5);
  const auto b = s.cube(1.0, Vec3(0, 0, 1.0 + h - 0.001), Quat(Eigen::AngleAxisd(M_PI / 4, Vec3::UnitX())));
  const ContactList contacts = s.polyhedra(a, b);
  ASSERT_EQ(contacts.size(), 2u);
  expect_normal(contacts, Vec3::UnitZ());
  EXPECT_TRUE(has_point(contacts, Vec3(-0.5, 0, 1.0 - 0.0005), 1e-12));
  EXPECT_TRUE(has_point(contacts, Vec3(0.5, 0, 1.0 - 0.0005), 1e-12));
  for (const Contact& c : contacts) EXPECT_NEAR(c.gap, -0.001, 1e-12);
}

// Vertex-face: a cube standing on a corner (main diagonal vertical): 1 point below the corner.
TEST(PolyhedronContacts, VertexFaceGivesOnePoint) {
  Scene s;
  const auto a = s.cube(2.0, Vec3::Zero());
  const Quat corner_down = rubble::testing::rotation_between(Vec3(-1, -1, -1).normalized(), -Vec3::UnitZ());
  const double half_diagonal = std::sqrt(3.0) / 2.0;
  const auto b = s.cube(1.0, Vec3(0.1, 0.2, 1.0 + half_diagonal + 0.004), corner_down);
  const ContactList contacts = s.polyhedra(a, b);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, 0.004, 1e-12);
  EXPECT_TRUE(has_point(contacts, Vec3(0.1, 0.2, 1.002), 1e-12));
  expect_normal(contacts, Vec3::UnitZ());
}

// Edge-edge: crossed edges give 1 point at the crossing.
TEST(PolyhedronContacts, EdgeEdgeGivesOnePointAtTheCrossing) {
  Scene s;
  const double h = std::sqrt(0.5);
  const auto a = s.cube(1.0, Vec3::Zero(), Quat(Eigen::AngleAxisd(M_PI / 4, Vec3::UnitX())));
  const auto b = s.cube(1.0, Vec3(0.1, -0.2, 2 * h - 0.002), Quat(Eigen::AngleAxisd(M_PI / 4, Vec3::UnitY())));
  const ContactList contacts = s.polyhedra(a, b);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, -0.002, 1e-12);
  // A's top edge runs along x at y = 0, B's bottom edge along y at x = 0.1.
  EXPECT_TRUE(has_point(contacts, Vec3(0.1, 0.0, h - 0.001), 1e-12));
  EXPECT_EQ(contacts[0].id.feature_a >> 30, 1u);  // edge
  EXPECT_EQ(contacts[0].id.feature_b >> 30, 1u);
}

TEST(PolyhedronContacts, BeyondTheAlertDistanceNothing) {
  Scene s;
  const auto a = s.cube(1.0, Vec3::Zero());
  const auto b = s.cube(1.0, Vec3(0, 0, 1.0 + 1.5 * alert));
  EXPECT_TRUE(s.polyhedra(a, b).empty());
  const auto c = s.cube(1.0, Vec3(0.3, 0, 1.0 + 0.5 * alert));
  EXPECT_EQ(s.polyhedra(a, c).size(), 4u);
}

TEST(PolyhedronContacts, IdsPersistUnderSmallMotion) {
  Scene s;
  const auto a = s.cube(1.0, Vec3::Zero());
  const auto b = s.cube(1.0, Vec3(0.2, 0.3, 0.999));
  const ContactList before = s.polyhedra(a, b);
  s.state.position[b] += Vec3(1e-4, -2e-4, 1e-4);
  s.state.orientation[b] = Quat(Eigen::AngleAxisd(1e-4, Vec3(1, 2, 3).normalized()));
  const ContactList after = s.polyhedra(a, b);
  ASSERT_EQ(before.size(), after.size());
  auto ids = [](ContactList c) {
    std::vector<ContactId> out;
    for (const Contact& x : c) out.push_back(x.id);
    std::sort(out.begin(), out.end());
    return out;
  };
  EXPECT_EQ(ids(before), ids(after));
}

// Two stacked cubes whose faces are flush but shifted sideways by a hair and tilted by 1e-9 rad
// (what a resting tower looks like after a few steps): the corners of each face lie a hair
// outside the other face, where the other cube's nearly vertical side faces would give a bogus
// height (offset / tiny slope). Reference: all four corner points, with the true gaps (below the
// tilt times the side).
TEST(PolyhedronContacts, FlushFacesShiftedByAHairKeepFourPointsAndTheirGaps) {
  for (const double tilt : {1e-9, 1e-8, 1e-7}) {
    for (const double shift : {1e-9, 1e-7, 1e-5}) {
      Scene s;
      const auto a = s.cube(0.05, Vec3::Zero());
      const auto b =
          s.cube(0.05, Vec3(shift, -0.5 * shift, 0.05), Quat(Eigen::AngleAxisd(tilt, Vec3(1, 1, 0).normalized())));
      const ContactList contacts = s.polyhedra(a, b);
      {
        auto in_world = [&](std::uint32_t body) {
          return PolyhedronInWorld{&s.model.polyhedra[static_cast<std::size_t>(s.model.shape_index[body])],
                                   s.state.position[body], s.state.orientation[body].toRotationMatrix()};
        };
        const CommonPlane plane = find_common_plane(in_world(a), in_world(b), nullptr, 10.0);
        // The plane is the faces' (GJK's closest-points direction is round-off at this distance).
        EXPECT_LT((plane.normal - Vec3::UnitZ()).norm(), 2 * tilt) << "shift " << shift << " tilt " << tilt;
        EXPECT_LT(std::abs(plane.gap), 0.05 * tilt) << "shift " << shift << " tilt " << tilt;
      }
      ASSERT_EQ(contacts.size(), 4u) << "shift " << shift << " tilt " << tilt;
      for (const Contact& c : contacts)
        EXPECT_LT(std::abs(c.gap), 0.05 * tilt + 1e-12) << "shift " << shift << " tilt " << tilt;
    }
  }
}

// Whatever the reduction keeps (4 points for a flat patch, up to 8 where the gap over the plane
// is not affine), the deepest point stays a contact point. Reference: the common plane's own gap
// (the separation of the two bodies along the optimal normal), on 500 random cube pairs near
// contact; at most 8 points per pair.
TEST(PolyhedronContacts, DeepestPointIsAlwaysAContactPoint) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  auto random_rotation = [&] { return Quat(uniform(rng), uniform(rng), uniform(rng), uniform(rng)).normalized(); };
  int checked = 0;
  for (int trial = 0; trial < 500; ++trial) {
    Scene t;
    const auto a = t.cube(1.0, Vec3::Zero(), random_rotation());
    const auto b =
        t.cube(1.0, Vec3(0.2 * uniform(rng), 0.2 * uniform(rng), 1.0 + 0.4 * uniform(rng)), random_rotation());
    auto in_world = [&](std::uint32_t body) {
      return PolyhedronInWorld{&t.model.polyhedra[static_cast<std::size_t>(t.model.shape_index[body])],
                               t.state.position[body], t.state.orientation[body].toRotationMatrix()};
    };
    const CommonPlane plane = find_common_plane(in_world(a), in_world(b), nullptr, 10.0);
    if (!plane.complete || plane.gap >= alert) continue;
    const ContactList contacts = t.polyhedra(a, b);
    ASSERT_FALSE(contacts.empty()) << "trial " << trial;
    double deepest = std::numeric_limits<double>::infinity();
    for (const Contact& c : contacts) deepest = std::min(deepest, c.gap);
    EXPECT_NEAR(deepest, plane.gap, 1e-9) << "trial " << trial;
    EXPECT_LE(contacts.size(), 8u);
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(PolyhedronContacts, PlaneWallGivesTheFaceCorners) {
  Scene s;
  const auto floor = s.plane(Vec3(0, 0, -1), Vec3::UnitZ());
  const auto b = s.cube(1.0, Vec3(3, 4, -0.502));
  ContactList contacts;
  collide_plane_polyhedron(s.model, s.state, floor, b, alert, contacts);
  ASSERT_EQ(contacts.size(), 4u);
  expect_normal(contacts, Vec3::UnitZ());
  for (const Contact& c : contacts) {
    EXPECT_NEAR(c.gap, -0.002, 1e-12);
    EXPECT_NEAR(c.point.z(), -1.001, 1e-12);
    EXPECT_EQ(c.id.body_a, floor);
  }
  // Tilted about x by 0.1 rad: one edge down, 2 points (the other edge is far above the alert).
  s.state.orientation[b] = Quat(Eigen::AngleAxisd(0.1, Vec3::UnitX()));
  contacts.clear();
  collide_plane_polyhedron(s.model, s.state, floor, b, alert, contacts);
  EXPECT_EQ(contacts.size(), 2u);
}

TEST(PolyhedronContacts, BoxWallActsLikeAPolyhedron) {
  Scene s;
  const auto wall = s.box(Vec3(5, 5, 0.5), Vec3(0, 0, -0.5));
  const auto b = s.cube(1.0, Vec3(1, 1, 0.499));
  ContactList contacts;
  Vec3 normal;
  collide_box_polyhedron(s.model, s.state, wall, b, alert, nullptr, contacts, normal);
  ASSERT_EQ(contacts.size(), 4u);
  expect_normal(contacts, Vec3::UnitZ());
  for (const Contact& c : contacts) EXPECT_NEAR(c.gap, -0.001, 1e-12);
  EXPECT_NEAR((normal - Vec3::UnitZ()).norm(), 0.0, 1e-12);
}

// Sphere against a cube: face, edge and corner regions, inside, and both id orders.
TEST(PolyhedronContacts, SphereAgainstPolyhedron) {
  Scene s;
  const auto ball = s.sphere(0.25, Vec3(0, 0, 0.7));  // above the top face: gap -0.05
  const auto cube = s.cube(1.0, Vec3::Zero());
  ContactList contacts;
  collide_sphere_polyhedron(s.model, s.state, ball, cube, 0.1, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, -0.05, 1e-12);
  EXPECT_NEAR((contacts[0].frame.col(0) + Vec3::UnitZ()).norm(), 0.0, 1e-12);  // from the sphere (a) to the cube (b)
  EXPECT_NEAR((contacts[0].point - Vec3(0, 0, 0.475)).norm(), 0.0, 1e-12);

  // Near a corner: distance from (0.5,0.5,0.5) to the centre.
  s.state.position[ball] = Vec3(0.6, 0.7, 0.8);
  contacts.clear();
  collide_sphere_polyhedron(s.model, s.state, ball, cube, 0.5, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  const Vec3 offset = Vec3(0.1, 0.2, 0.3);
  EXPECT_NEAR(contacts[0].gap, offset.norm() - 0.25, 1e-12);
  EXPECT_NEAR((contacts[0].frame.col(0) + offset.normalized()).norm(), 0.0, 1e-9);

  // Centre inside, nearest face +x.
  s.state.position[ball] = Vec3(0.4, 0.1, 0.0);
  contacts.clear();
  collide_sphere_polyhedron(s.model, s.state, ball, cube, 0.1, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, -0.1 - 0.25, 1e-12);
  EXPECT_NEAR((contacts[0].frame.col(0) + Vec3::UnitX()).norm(), 0.0, 1e-12);

  // Cube first: the normal points from the cube to the sphere.
  Scene t;
  const auto cube2 = t.cube(1.0, Vec3::Zero());
  const auto ball2 = t.sphere(0.25, Vec3(0, -0.7, 0));
  contacts.clear();
  collide_sphere_polyhedron(t.model, t.state, cube2, ball2, 0.1, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR((contacts[0].frame.col(0) + Vec3::UnitY()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(contacts[0].gap, -0.05, 1e-12);
}

}  // namespace
}  // namespace rubble
