#pragma once
// The model: everything about a scene that does not change during a run (shapes, masses,
// inertia, materials, the contact-law table). Built once, then shared read-only by every stage.
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.hpp"
#include "core/shapes.hpp"
#include "core/state.hpp"

namespace rubble {

/// A bulk material: the density that turns a shape's volume into mass.
struct Material {
  std::string name;    ///< as written in the scene file
  double density = 0;  ///< kg/m^3
};

/// The frictional contact law between two materials (Signorini and Coulomb plus Newton restitution).
struct ContactLaw {
  double friction_coefficient = 0.0;  ///< Coulomb's mu >= 0
  double normal_restitution = 0.0;    ///< Newton's e_n in [0, 1]
  /// Cohesion: the pull-off force of a pair of bodies in contact, N (>= 0). A cohesive contact may
  /// pull up to this force before it opens, and Coulomb's cone acts on the normal force including
  /// it (the cone shifted by the cohesive impulse; nlgs_solver/README.md, "Cohesion").
  double cohesion = 0.0;
  /// Work of adhesion W, J/m^2 (>= 0): a size-dependent pull-off force 2 pi W r_eff added to
  /// `cohesion`, r_eff = r_a r_b / (r_a + r_b) from the grains' volume-equivalent radii (the grain's
  /// own against a wall): the Derjaguin-Muller-Toporov pull-off force of two spheres (Derjaguin,
  /// Muller & Toporov 1975); van der Waals cohesion of regolith grains scales the same way,
  /// linearly with the reduced radius (Scheeres et al. 2010).
  double work_of_adhesion = 0.0;
  /// Rolling resistance mu_r >= 0 (dimensionless): the relative rolling of two spheres (or a
  /// sphere and a wall) is resisted by an angular impulse of norm at most mu_r r_eff r_n
  /// (nlgs_solver/README.md, "Rolling and twisting resistance"). Sphere contacts only.
  double rolling_friction = 0.0;
  /// Twisting resistance mu_t >= 0: the relative spin about the normal is resisted by an angular
  /// impulse of at most mu_t r_eff r_n. Sphere contacts only.
  double twisting_friction = 0.0;
  /// Tangential restitution e_t in [0, 1] (last, so that positional initialisers of the members
  /// above keep their meaning): Coulomb's law holds for the weighted tangential
  /// velocity u_t+ + e_t u_t- (Moreau 1988; Fremond 2002), so a sticking impact reverses the
  /// contact point's sliding velocity times e_t (a superball), and e_t = 0 is plain Coulomb
  /// (nlgs_solver/README.md, "Tangential restitution").
  double tangential_restitution = 0.0;
  /// Whether the law has any cohesion.
  bool cohesive() const { return cohesion > 0.0 || work_of_adhesion > 0.0; }
  /// Whether the law resists rolling or twisting.
  bool resists_rotation() const { return rolling_friction > 0.0 || twisting_friction > 0.0; }
  /// Whether the law has tangential restitution.
  bool restitutes_tangentially() const { return tangential_restitution > 0.0; }
};

/// Contact laws by material pair, symmetric: law(a, b) == law(b, a).
struct ContactLawTable {
  int material_count = 0;        ///< number of materials
  std::vector<ContactLaw> laws;  ///< material_count^2 entries, row-major

  /// Resizes to n materials, every pair getting `fallback`.
  void reset(int n, const ContactLaw& fallback) {
    material_count = n;
    laws.assign(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), fallback);
  }
  /// Sets the law of the pair (a, b) and (b, a).
  void set(int a, int b, const ContactLaw& law) {
    laws[index(a, b)] = law;
    laws[index(b, a)] = law;
  }
  /// The law between materials a and b.
  const ContactLaw& get(int a, int b) const { return laws[index(a, b)]; }
  /// Position of the pair (a, b) in `laws` (row-major).
  std::size_t index(int a, int b) const {
    return static_cast<std::size_t>(a) * static_cast<std::size_t>(material_count) + static_cast<std::size_t>(b);
  }
  /// Whether any pair's law has cohesion (a scene without it pays nothing for it).
  bool any_cohesive() const {
    for (const ContactLaw& law : laws)
      if (law.cohesive()) return true;
    return false;
  }
  /// Whether any pair's law resists rolling or twisting.
  bool any_resists_rotation() const {
    for (const ContactLaw& law : laws)
      if (law.resists_rotation()) return true;
    return false;
  }
  /// Whether any pair's law has tangential restitution.
  bool any_tangential_restitution() const {
    for (const ContactLaw& law : laws)
      if (law.restitutes_tangentially()) return true;
    return false;
  }
};

/// A prescribed rigid motion (a driven body: a moving wall, a plate, an impactor): the velocity of
/// the body's reference point (a grain's centre of mass, a plane's point, a box's centre) and its
/// angular velocity about that point, as functions of time. Linear between the knots, held at the
/// first knot's value before it and at the last one's after it; one knot is a constant motion.
/// A driven body pushes grains but is not pushed: the solver sees it with infinite mass, as a wall.
struct PrescribedMotion {
  std::vector<double> time;            ///< s (the run's clock, State::time), strictly increasing
  std::vector<Vec3> velocity;          ///< m/s, world frame, one per knot
  std::vector<Vec3> angular_velocity;  ///< rad/s, world frame, one per knot
};

/// A rigid body's velocity: of its reference point, and its angular velocity.
struct RigidVelocity {
  Vec3 linear = Vec3::Zero();   ///< m/s
  Vec3 angular = Vec3::Zero();  ///< rad/s
};

/// The prescribed velocity at `time`, s (linear interpolation between knots, held outside them).
RigidVelocity prescribed_velocity(const PrescribedMotion& motion, double time);

/// The immutable part of a scene. Per-body data is stored as structure of arrays, indexed by
/// body id; walls are bodies with zero inverse mass and inertia.
struct Model {
  // --- per body ---
  std::vector<ShapeKind> shape_kind;    ///< which table shape_index points into
  std::vector<int> shape_index;         ///< index into spheres / polyhedra / planes / boxes
  std::vector<int> material;            ///< index into materials
  std::vector<double> mass;             ///< kg (0 for walls, meaning infinite)
  std::vector<double> inverse_mass;     ///< 1/kg (0 for walls)
  std::vector<Vec3> principal_inertia;  ///< kg m^2, body frame (0 for walls)
  std::vector<Vec3> inverse_inertia;    ///< 1/(kg m^2), body frame (0 for walls)
  std::vector<double> bounding_radius;  ///< m, radius of the sphere around the body origin (inf for planes)
  std::vector<double> volume;           ///< m^3 (0 for walls)
  /// Index into prescribed_motions of a driven body (its velocity is prescribed), -1 for a free
  /// grain or a still wall. Driven bodies also have zero inverse mass and inertia (is_fixed).
  std::vector<int> motion_of_body;

  // --- shape tables ---
  std::vector<Sphere> spheres;              ///< sphere shapes
  std::vector<ConvexPolyhedron> polyhedra;  ///< convex polyhedron shapes
  std::vector<Plane> planes;                ///< plane walls
  std::vector<Box> boxes;                   ///< box walls

  std::vector<PrescribedMotion> prescribed_motions;  ///< the motions of driven bodies
  std::vector<std::size_t> driven_bodies;            ///< body ids of the driven bodies, increasing

  // --- materials and contact laws ---
  std::vector<Material> materials;  ///< by material id
  ContactLawTable contact_laws;     ///< by material pair

  /// Number of bodies, walls included.
  std::size_t body_count() const { return shape_kind.size(); }
  /// True for bodies of infinite mass, which contact impulses never move: walls and driven bodies.
  bool is_fixed(std::size_t body) const { return inverse_mass[body] == 0.0; }
  /// True for a driven body: it moves with its PrescribedMotion (walls without one stay still).
  bool is_driven(std::size_t body) const { return body < motion_of_body.size() && motion_of_body[body] >= 0; }
  /// The prescribed velocity of a driven body at `time`, s.
  RigidVelocity driven_velocity(std::size_t body, double time) const {
    return prescribed_velocity(prescribed_motions[static_cast<std::size_t>(motion_of_body[body])], time);
  }
  /// True for grains (sphere or polyhedron).
  bool is_grain(std::size_t body) const {
    return shape_kind[body] == ShapeKind::sphere || shape_kind[body] == ShapeKind::polyhedron;
  }
  /// Radius of a sphere body (only valid when shape_kind[body] == sphere).
  double sphere_radius(std::size_t body) const { return spheres[static_cast<std::size_t>(shape_index[body])].radius; }
};

/// Adds a sphere grain of the given radius and material to the model; returns its body id.
int add_sphere(Model& model, double radius, int material);
/// Adds a fixed plane wall with the given body-frame normal; returns its body id.
int add_plane_wall(Model& model, const Vec3& normal, int material);
/// Adds a fixed box wall with the given half extents; returns its body id.
int add_box_wall(Model& model, const Vec3& half_extents, int material);
/// Adds a grain with the given convex polyhedron shape (already in its principal body frame),
/// mass properties given by the caller; returns its body id.
int add_polyhedron(Model& model, ConvexPolyhedron shape, double volume, const Vec3& principal_inertia_per_density,
                   int material);

/// Makes `body` a driven body moving with `motion` (checked: knots increasing, one velocity per
/// knot): its mass, inertia and their inverses become 0, the solver's infinite mass. Throws
/// std::invalid_argument on a malformed motion.
void drive_body(Model& model, int body, PrescribedMotion motion);

/// Sets the velocities of the driven bodies in `state` to their prescribed values at state.time
/// (a scene's start, or the state a branch starts from).
void set_prescribed_velocities(const Model& model, State& state);

/// The model of the first `bodies` bodies: the per-body arrays cut there, the shape, material,
/// contact-law and motion tables whole (a run with an [[inflow]] steps the bodies in play, always
/// the first ones: simulation/inflow.hpp).
Model model_prefix(const Model& model, std::size_t bodies);
/// The state of the first `bodies` bodies (time and step kept).
State state_prefix(const State& state, std::size_t bodies);

/// World-frame inverse inertia tensor R diag(I^-1) R^T of a body with the given orientation.
inline Mat3 world_inverse_inertia(const Model& model, std::size_t body, const Quat& orientation) {
  const Mat3 rotation = orientation.toRotationMatrix();
  return rotation * model.inverse_inertia[body].asDiagonal() * rotation.transpose();
}

}  // namespace rubble
