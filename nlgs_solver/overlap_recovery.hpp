#pragma once
// Overlap recovery without kinetic energy: a position-level pass after the velocity solve (the
// "split impulse" of Catto 2006 and of Bullet, a pseudo-velocity projection as in Cottle-type
// position correction, Baraff 1989). The contact law acts on the velocities alone; what overlap
// remains at the end of the step beyond an allowed depth is removed by displacements computed as a
// frictionless contact problem on pseudo-velocities w:
//     0 <= p_a  _|_  w_n,a - c_a >= 0,   c_a = min(beta (-g_end,a - s_a) / h, v_max)
// where g_end = g_m + theta h U_n(v_{n+1}) is the contact's gap predicted at the end of the step and
// s_a the allowed overlap. The positions then move by h w (integrator.hpp, finish_step) while the
// velocities stay those of the non-smooth law: no kinetic energy is created, unlike a separation
// velocity in the Signorini target (which turned a 4.4 m/s e_n = 0 impact into a 0.2-0.4 m/s
// rebound and kept a pile of polyhedra from coming to rest).
#include "core/contact.hpp"
#include "core/integrator.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// Settings of the overlap recovery (part of SolverOptions).
struct OverlapRecoveryOptions {
  /// beta: fraction of the overlap beyond the allowed depth removed per step (0 disables).
  double fraction = 0.2;
  /// v_max, m/s: cap on a contact's pseudo-velocity, i.e. on the displacement per step (v_max h).
  double max_velocity = 1.0;
  /// s as a fraction of the smaller bounding radius of the two bodies (walls: the grain's alone).
  /// Overlaps below it are left alone: detection of polyhedra reports persistent overlaps of
  /// ~1e-4 of a grain's size where the common plane's supports do not meet, which moving the
  /// grain does not remove.
  double allowed_overlap = 1e-3;
  /// Projected Gauss-Seidel sweeps at most (the problem is frictionless and usually small).
  int max_sweeps = 50;
};

/// What the recovery did in a step.
struct OverlapRecoveryStats {
  std::size_t overlapping = 0;  ///< contacts whose overlap exceeded the allowed depth
  double deepest = 0.0;         ///< m, largest predicted end-of-step overlap (-g_end), 0 if none
  int sweeps = 0;               ///< projected Gauss-Seidel sweeps done
};

/// Computes the pseudo-velocities (`displacement_velocity`: per body, linear and angular, world
/// frame; left empty when no contact overlaps beyond its allowed depth) that remove the fraction
/// `options.fraction` of every excess overlap. `state` holds the midpoint configuration the
/// contacts were prepared at (arms, frames, Delassus blocks) and `velocity` the end-of-step
/// velocities. Deterministic: the contacts are swept serially in list order.
OverlapRecoveryStats recover_overlaps(const Model& model, const State& state, const ContactList& contacts,
                                      const BodyVelocities& velocity, const IntegratorOptions& integrator,
                                      const OverlapRecoveryOptions& options, BodyVelocities& displacement_velocity);

}  // namespace rubble
