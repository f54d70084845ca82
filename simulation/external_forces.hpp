#pragma once
// Stage 2 of the step, external_forces: the force on every body at the midpoint configuration
// q_m (gravity: none, uniform, a central mass, or self-gravity by direct sum or tree, possibly
// held over several steps), the grains' potential energy in that field, and the work of the
// forces over a displacement (the energy monitor's bookkeeping).
#include <optional>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"
#include "core/units.hpp"
#include "gravity/gravity.hpp"
#include "simulation/step_carry.hpp"

namespace rubble {

/// A fixed point mass M at `centre` pulling every grain (Kind::central):
///   a(x) = -G M (x - c) / (|x - c|^2 + eps^2)^(3/2),
/// the Plummer-softened Kepler field (Plummer 1911; Binney & Tremaine, Galactic Dynamics, eq. 2.44a):
/// exact 1/r^2 for |x - c| >> eps, finite (and going linearly to 0) at the centre, so a grain
/// reaching c meets no singular force.
struct CentralField {
  Vec3 centre = Vec3::Zero();                ///< c, m
  double mass = 0.0;                         ///< M, kg
  double G = units::gravitational_constant;  ///< gravitational constant, m^3 kg^-1 s^-2
  double softening = 0.0;                    ///< eps, m (0: the exact point-mass field)
};

/// The acceleration of the central field at `position`.
Vec3 central_acceleration(const CentralField& field, const Vec3& position);

/// Which gravity acts on the grains.
struct GravitySettings {
  enum class Kind { none, uniform, self, central };
  Kind kind = Kind::none;                  ///< none, a uniform field, self-gravity or a central mass
  Vec3 acceleration = Vec3::Zero();        ///< m/s^2, for Kind::uniform
  gravity::GravityOptions self_gravity{};  ///< for Kind::self (direct or tree, G, theta, order)
  CentralField central{};                  ///< for Kind::central
  /// For Kind::self: the field is evaluated every `evaluate_every` steps and held in between
  /// (StepCarry::held_gravity); 1 = every step, the exact scheme.
  int evaluate_every = 1;
};

/// Self-gravity's scratch arrays, kept from step to step only so that their memory is reused: the
/// grains' positions and masses as the gravity library takes them, the field it returns, and the
/// tree's own memory (gravity::FieldWorkspace). Not state: a checkpoint saves none of it.
struct SelfGravityWorkspace {
  std::vector<std::size_t> grains;          ///< the bodies that feel self-gravity (not fixed), in body order
  std::vector<double> positions;            ///< 3 per grain, m
  std::vector<double> masses;               ///< per grain, kg
  std::vector<double> acceleration;         ///< 3 per grain, m/s^2
  std::vector<double> potential;            ///< per grain, J/kg
  std::vector<Vec3> acceleration_per_body;  ///< m/s^2, zero for fixed bodies
  gravity::FieldWorkspace field;            ///< the tree's memory
};

/// The external force on every body at `state` (taken at the midpoint configuration q_m by the
/// step) into `force` (walls and other fixed bodies get none). With evaluate_every = k > 1 the
/// self-gravity field is evaluated at the midpoints of steps n, n+k, ... and held in between in
/// `carry.held_gravity`. Returns the grains' gravitational potential energy at `state`, or
/// nothing when a held self-gravity field was used (it was evaluated at an earlier step).
/// `scratch`: self-gravity's arrays, reused from call to call.
std::optional<double> compute_external_forces(const Model& model, const State& state, const GravitySettings& gravity,
                                              StepCarry& carry, SelfGravityWorkspace& scratch,
                                              std::vector<Vec3>& force);

/// Work of the forces `force` over the displacement `scale` * `velocity` of every grain, J
/// (0 when `velocity` is empty).
double work_of_forces(const Model& model, const std::vector<Vec3>& force, const std::vector<Vec3>& velocity,
                      double scale);

/// The grains' gravitational potential energy in the field `gravity` at `state`, J (self-gravity:
/// 1/2 sum m_i phi_i by the configured direct sum or tree; uniform: -sum m g.x; central mass:
/// -sum G M m / sqrt(r^2 + eps^2)).
double gravitational_potential_energy(const Model& model, const State& state, const GravitySettings& gravity);

}  // namespace rubble
