#pragma once
// Narrow phase involving convex polyhedra: common-plane method (Cundall 1988; the LMGC90 accretion paper, sec. 2.2).
#include <array>
#include <vector>

#include "contact_detection/common_plane.hpp"
#include "contact_detection/contact_polygon.hpp"
#include "core/contact.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Two polyhedra on their common plane, seen from A's frame (n from A to B, tangents t and s):
/// what each stage of the contact points reads (narrow_phase_polyhedra.cpp), with their working
/// buffers. Refilled for every pair; part of PolyhedronScratch.
struct PairOnPlane {
  const PolyhedronPair* pair = nullptr;  ///< the pair, B moved into A's frame (pair->vb)
  double size = 0.0;                     ///< m, the smaller bounding radius
  Vec3 n = Vec3::UnitZ();                ///< the plane's normal in A's frame
  Vec3 t = Vec3::UnitX();                ///< the plane's first tangent in A's frame
  Vec3 s = Vec3::UnitY();                ///< the plane's second tangent in A's frame
  double top_a = 0.0;                    ///< m, A's extreme height along n
  double bottom_b = 0.0;                 ///< m, B's extreme height along -n
  double linear_tolerance = 0.0;         ///< m, 1e-7 of the size: round-off of the caps' hulls
  /// m, features closer than this in the plane count as coincident, and a vertex this close outside
  /// the other polygon still counts as inside: stacked, aligned faces then keep the same contact
  /// ids (hence warm starts) while they creep by less than 1e-3 of the grain size.
  double feature_tolerance = 0.0;
  std::vector<double> heights_a;  ///< m, n.x of every vertex of A
  std::vector<double> heights_b;  ///< m, n.y of every vertex of B (in A's frame)
  /// m, (t.x, s.x) of the vertices of A within the alert caps' depth (others unset)
  std::vector<contact_polygon::Vec2> plane_a;
  std::vector<contact_polygon::Vec2> plane_b;  ///< m, the same for B
  std::vector<int> cap_vertices_a;             ///< A's vertices within the alert caps' depth, in increasing order
  std::vector<int> cap_vertices_b;             ///< B's vertices within the alert caps' depth, in increasing order
  /// A's faces turned towards n, as (m.t, m.s, m.n, offset): its upper surface.
  std::vector<std::array<double, 4>> faces_up;
  /// B's faces turned against n, as (m.t, m.s, m.n, offset) in A's frame: its lower surface.
  std::vector<std::array<double, 4>> faces_down;
  int face_a = 0;                      ///< A's face most turned towards n: the "face" side of vertex-face points
  int face_b = 0;                      ///< B's face most turned against n
  contact_polygon::Polygon cap_a;      ///< buffer: A's cap before its hull
  contact_polygon::Polygon cap_b;      ///< buffer: B's cap before its hull
  contact_polygon::Polygon support_a;  ///< A's support cap (hull)
  contact_polygon::Polygon support_b;  ///< B's support cap (hull)
  contact_polygon::Polygon alert_a;    ///< A's alert cap (hull)
  contact_polygon::Polygon alert_b;    ///< B's alert cap (hull)
  contact_polygon::HullBuffers hull;   ///< buffers of hull_2d
  contact_polygon::Polygon ridges_a;   ///< buffer: A's ridge edges, as pairs of ends
  contact_polygon::Polygon ridges_b;   ///< buffer: B's ridge edges, as pairs of ends
  std::vector<contact_polygon::Candidate> candidates;  ///< buffer: every point of the intersection
  std::vector<contact_polygon::Candidate> active;      ///< buffer: those with a gap below the alert distance
  std::vector<contact_polygon::Candidate> kept;        ///< buffer: the points kept
  contact_polygon::ReductionBuffers reduction;         ///< buffers of add_off_plane_points
};

/// Working space of the polyhedral narrow phase, owned by the caller (one per thread) and reused
/// from pair to pair: once its buffers have grown a pair allocates nothing but its contacts.
/// Holds no result: the contacts are the same whatever the scratch has seen before.
struct PolyhedronScratch {
  PolyhedronPair pair;  ///< the pair in A's frame, shared by the common-plane search and the contact points
  PairOnPlane plane;    ///< the contact points' data on the common plane
};

/// Polyhedron a against polyhedron b (a < b): 1 to 4 contact points on the common plane.
/// `previous_common_normal` (may be null) warm-starts the search; `common_normal` receives the new one.
/// B is moved into A's frame once, for both the plane and the points, in `scratch`.
void collide_polyhedron_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                                   double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                                   Vec3& common_normal, PolyhedronScratch& scratch);
/// The same with a scratch of its own (allocates; for tests and one-off calls).
void collide_polyhedron_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                                   double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                                   Vec3& common_normal);
/// Sphere against polyhedron, a < b in id order, either may be the sphere; normal from a to b.
void collide_sphere_polyhedron(const Model& model, const State& state, std::uint32_t a, std::uint32_t b,
                               double alert_distance, ContactList& contacts);
/// Plane wall against a polyhedron grain.
void collide_plane_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                              double alert_distance, ContactList& contacts);
/// Box wall against a polyhedron grain (the box as an 8-vertex polyhedron, through `scratch`).
void collide_box_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                            double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                            Vec3& common_normal, PolyhedronScratch& scratch);
/// The same with a scratch of its own (allocates; for tests and one-off calls).
void collide_box_polyhedron(const Model& model, const State& state, std::uint32_t wall, std::uint32_t grain,
                            double alert_distance, const Vec3* previous_common_normal, ContactList& contacts,
                            Vec3& common_normal);

}  // namespace rubble
