#pragma once
// The local problem of one contact, solved exactly (the kernel of every NLGS sweep).
#include "core/math.hpp"

namespace rubble {

/// Result of the local solve.
struct LocalSolution {
  Vec3 impulse = Vec3::Zero();                                          ///< r = (r_n, r_t, r_s)
  enum class Regime { open, sticking, sliding } regime = Regime::open;  ///< which branch of the law holds
};

/// Finds r such that u = W r + u_free satisfies Signorini-Coulomb on this contact alone:
///   0 <= r_n _|_ u_n >= 0,  ||r_T|| <= mu r_n,  and r_T = -mu r_n u_T/||u_T|| when u_T != 0.
/// Enumerates the three regimes of the law (Jean 1999; Alart & Curnier 1991 give the same
/// solution set): open (r = 0 when u_free,n >= 0), sticking (u = 0, r = -W^-1 u_free inside the
/// cone), else sliding: in closed form when W_TT is isotropic and W_nT = 0 (spheres; d is then
/// along u_free_T), otherwise by Newton on the angle of the sliding direction d (u_T(d) along d),
/// with a bracketed angle search as fallback for strongly coupled blocks.
LocalSolution solve_local_contact(const Mat3& delassus, const Vec3& free_velocity, double friction_coefficient);

/// The same solve with W^-1 given: the sweeps solve each contact hundreds of times a step with the
/// same W, so they invert it once (CompactProblem::Point::delassus_inverse) instead of in every
/// sticking test. `delassus_inverse` must be delassus.inverse() for the result to be the same bits.
LocalSolution solve_local_contact(const Mat3& delassus, const Mat3& delassus_inverse, const Vec3& free_velocity,
                                  double friction_coefficient);

}  // namespace rubble
