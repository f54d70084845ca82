#pragma once
// Narrow phase for spheres against spheres and walls (planes, boxes).
#include "core/contact.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Sphere-sphere: one contact point on the line of centres, normal from a to b.
void collide_sphere_sphere(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                           double alert_distance, ContactList& contacts);

/// Plane wall `wall` against sphere `sphere`: one contact point, normal = the plane's normal.
void collide_plane_sphere(const Model& model, const State& state, std::uint32_t wall, std::uint32_t sphere,
                          double alert_distance, ContactList& contacts);

/// Box wall `wall` against sphere `sphere`: one contact point at the box's closest point.
void collide_box_sphere(const Model& model, const State& state, std::uint32_t wall, std::uint32_t sphere,
                        double alert_distance, ContactList& contacts);

}  // namespace rubble
