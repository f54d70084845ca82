#pragma once
// The local problem of one contact, solved exactly (the kernel of every NLGS sweep).
#include <cmath>

#include "core/math.hpp"
#include "nlgs_solver/coulomb.hpp"

namespace rubble {

/// Result of the local solve.
struct LocalSolution {
  Vec3 impulse = Vec3::Zero();                                          ///< r = (r_n, r_t, r_s)
  enum class Regime { open, sticking, sliding } regime = Regime::open;  ///< which branch of the law holds
};

/// Whether W's tangential block is isotropic and uncoupled from the normal row (W_nT = 0,
/// W_TT = w I, to 1e-12 of the diagonal): the block of two spheres, or of a sphere and a wall,
/// whose arms lie along the normal. Rounding leaves their off-diagonal terms at ~1e-17 of it.
inline bool isotropic_tangential_block(const Mat3& W) {
  return std::abs(W(0, 1)) + std::abs(W(0, 2)) <= 1e-12 * W(0, 0) &&
         std::abs(W(1, 2)) + std::abs(W(1, 1) - W(2, 2)) <= 1e-12 * W(1, 1);
}

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
/// `guess` (a sweep passes the contact's current impulse): where it has a tangential part, the
/// sliding Newton starts from its slip direction -r_T/||r_T|| (the same solution to the Newton's
/// tolerance, not the same bits).
LocalSolution solve_local_contact(const Mat3& delassus, const Mat3& delassus_inverse, const Vec3& free_velocity,
                                  double friction_coefficient, const Vec3& guess = Vec3::Zero());

/// The sliding solution on a coupled block (W_nT != 0 or W_TT anisotropic), out of line: Newton on
/// the slip direction's angle from `guess`'s slip direction, then from that of the sticking trial
/// -W^-1 u_free, then the bracketed angle scan; that trial projected onto the cone for a
/// degenerate block.
Vec3 slide_on_coupled_block(const Mat3& delassus, const Mat3& delassus_inverse, const Vec3& free_velocity,
                            double friction_coefficient, const Vec3& guess);

/// The law's solution for a closing contact (free_velocity,n < 0) from its sticking trial `stick`,
/// the impulse that makes u = 0 (-W^-1 u_free, or r - W^-1 u in a sweep): sticking when it lies
/// in the cone; else sliding, in closed form when frictionless or when the block is isotropic,
/// otherwise slide_on_coupled_block. Inline, as the sweeps' commonest regimes.
inline LocalSolution solve_from_sticking_trial(const Mat3& W, const Mat3& W_inverse, const Vec3& u_free,
                                               const Vec3& stick, double mu, const Vec3& guess) {
  LocalSolution solution{stick, LocalSolution::Regime::sticking};
  const double stick_tangential_squared = stick.y() * stick.y() + stick.z() * stick.z();
  if (stick.x() > 0.0 && stick_tangential_squared <= (mu * stick.x()) * (mu * stick.x())) return solution;
  solution.regime = LocalSolution::Regime::sliding;
  if (mu == 0.0) {
    // Frictionless: only the normal row, u_n = W_nn r_n + u_free_n = 0.
    solution.impulse = Vec3(-u_free.x() / W(0, 0), 0.0, 0.0);
  } else if (stick.x() > 0.0 && stick_tangential_squared > 0.0 && isotropic_tangential_block(W)) {
    // Sliding with an isotropic block: u_T = w r_T + u_free_T is along u_free_T whatever r_n, so
    // the slip direction is d = -stick_T/||stick_T|| and r_n = stick_n (= -u_free_n/W_nn), outside
    // the cone since it did not stick. Closed form: 12 ns a solve on sphere blocks against 69 by
    // the Newton, which takes two sliding candidates to confirm the same direction (a
    // microbenchmark; bench/RESULTS.md, "Sliding in closed form").
    const double scale = mu * stick.x() / std::sqrt(stick_tangential_squared);
    solution.impulse = Vec3(stick.x(), scale * stick.y(), scale * stick.z());
  } else {
    solution.impulse = slide_on_coupled_block(W, W_inverse, u_free, mu, guess);
  }
  return solution;
}

/// A sweep's update of one contact: its new impulse and the change from the current one.
struct LocalUpdate {
  Vec3 impulse;  ///< r_k after the update
  Vec3 change;   ///< impulse - r_k before: what the bodies' velocities receive
};

/// The sweep's update of a contact with impulse r, local velocity u and free velocity
/// u_free = u - W r: the local solution (solve_local_contact), relaxed by omega and, when
/// omega > 1, projected back onto the cone (projected SOR, Cryer 1971: over-relaxation steps past
/// the local solution and can leave the cone; under-relaxation mixes two admissible points). The
/// commonest regimes (sticking, frictionless, sliding on an isotropic block) are inline and
/// written from u rather than u_free: r - W^-1 u is the sticking impulse, so a sticking contact's
/// change is -omega W^-1 u, the shortest chain of operations from the bodies' velocities back to
/// them (a sweep is such a chain: each contact reads the velocities the one before wrote;
/// nlgs_solver/README.md, "The local solver"). Other sliding contacts are solved by Newton from
/// the current impulse's slip direction.
[[gnu::always_inline]] inline LocalUpdate relaxed_local_update(const Mat3& W, const Mat3& W_inverse, const Vec3& r,
                                                               const Vec3& u, const Vec3& u_free, double mu,
                                                               double relaxation) {
  const Vec3 step = W_inverse * u;
  LocalUpdate update{Vec3::Zero(), Vec3::Zero()};  // open: separating without any impulse
  bool sticks = false;
  if (u_free.x() < 0.0) {
    const LocalSolution local = solve_from_sticking_trial(W, W_inverse, u_free, r - step, mu, r);
    sticks = local.regime == LocalSolution::Regime::sticking;
    update.impulse = local.impulse;
  }
  if (sticks) {
    update.change = -relaxation * step;
    update.impulse = r + update.change;
  } else {
    if (relaxation != 1.0) update.impulse = relaxation * update.impulse + (1.0 - relaxation) * r;
    update.change = update.impulse - r;
  }
  if (relaxation > 1.0) {
    const Vec3 projected = project_onto_coulomb_cone(update.impulse, mu);
    if (projected != update.impulse) {
      update.impulse = projected;
      update.change = projected - r;
    }
  }
  return update;
}

}  // namespace rubble
