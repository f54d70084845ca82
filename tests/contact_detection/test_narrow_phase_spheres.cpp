// Sphere narrow phase against hand-computed geometry.
#include <gtest/gtest.h>

#include "contact_detection/narrow_phase_spheres.hpp"
#include "support/rotation.hpp"

namespace rubble {
namespace {

struct Scene {
  Model model;
  State state;
  Scene() {
    model.materials.push_back({"rock", 1000});
    model.contact_laws.reset(1, {});
  }
  void finish() { state.resize(model.body_count()); }
};

TEST(SphereSphere, GapNormalAndMidpoint) {
  Scene s;
  add_sphere(s.model, 1.0, 0);
  add_sphere(s.model, 0.5, 0);
  s.finish();
  s.state.position[1] = Vec3(0, 3, 4);  // distance 5, gap 3.5
  ContactList contacts;
  collide_sphere_sphere(s.model, s.state, 0, 1, 4.0, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, 3.5, 1e-15);
  EXPECT_LT((contacts[0].frame.col(0) - Vec3(0, 0.6, 0.8)).norm(), 1e-15);
  EXPECT_LT((contacts[0].point - Vec3(0, 0.6, 0.8) * (1.0 + 1.75)).norm(), 1e-14);
  contacts.clear();
  collide_sphere_sphere(s.model, s.state, 0, 1, 3.0, contacts);  // beyond the alert distance
  EXPECT_TRUE(contacts.empty());
}

TEST(PlaneSphere, SignedGapAlongTheRotatedNormal) {
  Scene s;
  add_plane_wall(s.model, Vec3::UnitZ(), 0);
  add_sphere(s.model, 0.2, 0);
  s.finish();
  s.state.position[0] = Vec3(0, 0, 1);
  s.state.orientation[0] = rubble::testing::rotation_between(Vec3::UnitZ(), Vec3(0, 1, 1).normalized());
  s.state.position[1] = Vec3(5, 0, 1.1);  // 0.1/sqrt(2) above the plane along its normal
  ContactList contacts;
  collide_plane_sphere(s.model, s.state, 0, 1, 1.0, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, 0.1 / std::sqrt(2.0) - 0.2, 1e-15);
  EXPECT_EQ(contacts[0].id.body_a, 0u);  // the wall first: n points from the wall into the grain
}

TEST(BoxSphere, FaceEdgeAndInsideCases) {
  Scene s;
  add_box_wall(s.model, Vec3(1, 2, 3), 0);
  add_sphere(s.model, 0.5, 0);
  s.finish();
  ContactList contacts;
  s.state.position[1] = Vec3(1.7, 0.3, 0);  // facing the +x face
  collide_box_sphere(s.model, s.state, 0, 1, 1.0, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, 0.2, 1e-15);
  EXPECT_LT((contacts[0].frame.col(0) - Vec3::UnitX()).norm(), 1e-15);
  contacts.clear();
  s.state.position[1] = Vec3(1.3, 2.4, 0);  // near the edge x = 1, y = 2
  collide_box_sphere(s.model, s.state, 0, 1, 1.0, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, 0.5 - 0.5, 1e-15);
  EXPECT_LT((contacts[0].frame.col(0) - Vec3(0.6, 0.8, 0)).norm(), 1e-14);
  contacts.clear();
  s.state.position[1] = Vec3(0.9, 0, 0);  // centre inside, 0.1 from the +x face
  collide_box_sphere(s.model, s.state, 0, 1, 1.0, contacts);
  ASSERT_EQ(contacts.size(), 1u);
  EXPECT_NEAR(contacts[0].gap, -0.1 - 0.5, 1e-15);
}

}  // namespace
}  // namespace rubble
