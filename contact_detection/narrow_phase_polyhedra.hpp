#pragma once
// Narrow phase involving convex polyhedra: common-plane method (Cundall 1988; the LMGC90 accretion paper, sec. 2.2).
#include "core/contact.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Polyhedron a against polyhedron b (a < b): 1 to 4 contact points on the common plane.
/// `previous_common_normal` (may be null) warm-starts the search; `common_normal` receives the new one.
void collide_polyhedron_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                                   double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                                   Vec3& common_normal);
/// Sphere against polyhedron, a < b in id order, either may be the sphere; normal from a to b.
void collide_sphere_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                               double alert_distance, ContactList& contacts);
/// Plane wall against a polyhedron grain.
void collide_plane_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                              double alert_distance, ContactList& contacts);
/// Box wall against a polyhedron grain.
void collide_box_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                            double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                            Vec3& common_normal);

}  // namespace rubble
