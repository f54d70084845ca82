#include "contact_detection/narrow_phase_spheres.hpp"

namespace rubble {
namespace {

/// Appends a contact with normal n (a -> b) whose surfaces are at `surface_a` and `surface_b`.
void push_contact(std::uint32_t a, std::uint32_t b, const Vec3& normal, const Vec3& surface_a, double gap,
                  ContactList& contacts) {
  Contact c;
  c.id = ContactId{a, b, 0, 0};
  c.frame = frame_from_normal(normal);
  c.gap = gap;
  c.point = surface_a + 0.5 * gap * normal;  // midway between the two surfaces
  contacts.push_back(c);
}

}  // namespace

void collide_sphere_sphere(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                           double alert_distance, ContactList& contacts) {
  const double radius_a = model.sphere_radius(a);
  const double radius_b = model.sphere_radius(b);
  const Vec3 centre_line = state.position[b] - state.position[a];
  const double distance = centre_line.norm();
  const double gap = distance - radius_a - radius_b;
  if (gap >= alert_distance) return;
  // Concentric spheres have no defined normal: pick +z so the result is still deterministic.
  const Vec3 normal = distance > 0.0 ? Vec3(centre_line / distance) : Vec3::UnitZ();
  push_contact(a, b, normal, state.position[a] + radius_a * normal, gap, contacts);
}

void collide_plane_sphere(const Model& model, const State& state, std::uint32_t wall, std::uint32_t sphere,
                          double alert_distance, ContactList& contacts) {
  const Plane& plane = model.planes[static_cast<std::size_t>(model.shape_index[wall])];
  const Vec3 normal = state.orientation[wall] * plane.normal;
  const double radius = model.sphere_radius(sphere);
  const double gap = normal.dot(state.position[sphere] - state.position[wall]) - radius;
  if (gap >= alert_distance) return;
  const Vec3 surface_sphere = state.position[sphere] - radius * normal;
  push_contact(wall, sphere, normal, surface_sphere - gap * normal, gap, contacts);
}

void collide_box_sphere(const Model& model, const State& state, std::uint32_t wall, std::uint32_t sphere,
                        double alert_distance, ContactList& contacts) {
  const Box& box = model.boxes[static_cast<std::size_t>(model.shape_index[wall])];
  const Mat3 rotation = state.orientation[wall].toRotationMatrix();
  const Vec3 centre = rotation.transpose() * (state.position[sphere] - state.position[wall]);
  const double radius = model.sphere_radius(sphere);
  const Vec3 closest = centre.cwiseMax(-box.half_extents).cwiseMin(box.half_extents);
  Vec3 normal_body;
  double distance;  // signed distance from the box surface to the sphere centre
  Vec3 surface_body;
  if (closest != centre) {
    const Vec3 offset = centre - closest;
    distance = offset.norm();
    normal_body = offset / distance;
    surface_body = closest;
  } else {
    // Centre inside the box: leave through the nearest face.
    const Vec3 depth = box.half_extents - centre.cwiseAbs();
    int axis = 0;
    depth.minCoeff(&axis);
    normal_body = Vec3::Zero();
    normal_body[axis] = centre[axis] >= 0.0 ? 1.0 : -1.0;
    distance = -depth[axis];
    surface_body = centre;
    surface_body[axis] = normal_body[axis] * box.half_extents[axis];
  }
  const double gap = distance - radius;
  if (gap >= alert_distance) return;
  push_contact(wall, sphere, rotation * normal_body, state.position[wall] + rotation * surface_body, gap, contacts);
}

}  // namespace rubble
