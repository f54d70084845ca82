#include "nlgs_solver/local_solver.hpp"

#include "nlgs_solver/coulomb.hpp"

#include <Eigen/LU>  // Matrix3d::inverse
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace rubble {
namespace {

using Vec2 = Eigen::Vector2d;

/// The sliding candidate for a sliding direction d (unit, tangent plane): r_T = -mu r_n d and
/// r_n chosen so that u_n = 0. Returns false when no positive r_n exists for this d.
struct SlidingCandidate {
  Vec3 impulse;
  Vec2 tangential_velocity;
};

bool sliding_candidate(const Mat3& W, const Vec3& u_free, double mu, const Vec2& d, SlidingCandidate& out) {
  // u_n = r_n (W_nn - mu W_nT d) + u_free_n = 0.
  const double normal_compliance = W(0, 0) - mu * (W(0, 1) * d.x() + W(0, 2) * d.y());
  if (!(normal_compliance > 0.0)) return false;
  const double r_n = -u_free.x() / normal_compliance;
  if (!(r_n >= 0.0)) return false;
  out.impulse = Vec3(r_n, -mu * r_n * d.x(), -mu * r_n * d.y());
  const Vec3 u = W * out.impulse + u_free;
  out.tangential_velocity = Vec2(u.y(), u.z());
  return true;
}

/// Misalignment of u_T with d: zero when u_T = s d (s >= 0 checked separately).
double misalignment(const SlidingCandidate& c, const Vec2& d) {
  return c.tangential_velocity.x() * d.y() - c.tangential_velocity.y() * d.x();
}

/// The sliding solution by Newton on the angle phi of the slip direction d, for the misalignment
/// f(phi) = u_T x d = 0, from the direction `d`. A plain fixed point d <- u_T/||u_T|| diverges near
/// the cone's boundary, where the slip is small; Newton on phi does not, since f' stays of the
/// order of mu r_n W_TT. The derivative is exact and d is turned without trigonometry (profiled:
/// sin/cos of a finite-difference derivative were ~15% of a step of the mixed deposit). With
/// d' = (-d_s, d_t) and D = W_nn - mu W_nT.d (so r_n = -u_free_n / D):
///   D' = -mu W_nT.d',  r_n' = -r_n D'/D,  r' = r_n' (1, -mu d) + r_n (0, -mu d'),  u' = W r',
///   f' = u'_T x d + u_T x d'.
/// The step turns d by -atan(delta) (d <- normalise(d - delta d')), which is a Newton step on
/// phi to second order, so the convergence stays quadratic. False when it does not converge in
/// 40 iterations to a true sliding solution (u_T along d).
bool slide_by_newton(const Mat3& W, const Vec3& u_free, double mu, Vec2 d, Vec3& impulse) {
  const auto cross = [](const Vec2& x, const Vec2& y) { return x.x() * y.y() - x.y() * y.x(); };
  SlidingCandidate c;
  for (int iteration = 0; iteration < 40; ++iteration) {
    if (!sliding_candidate(W, u_free, mu, d, c)) return false;
    const Vec2 turned(-d.y(), d.x());
    const double compliance = W(0, 0) - mu * (W(0, 1) * d.x() + W(0, 2) * d.y());
    const double compliance_rate = -mu * (W(0, 1) * turned.x() + W(0, 2) * turned.y());
    const double r_n = c.impulse.x();
    const double r_n_rate = -r_n * compliance_rate / compliance;
    const Vec3 impulse_rate(r_n_rate, -mu * (r_n_rate * d.x() + r_n * turned.x()),
                            -mu * (r_n_rate * d.y() + r_n * turned.y()));
    const Vec3 velocity_rate = W * impulse_rate;
    const double value = cross(c.tangential_velocity, d);
    const double derivative =
        cross(Vec2(velocity_rate.y(), velocity_rate.z()), d) + cross(c.tangential_velocity, turned);
    if (!std::isfinite(derivative) || derivative == 0.0) return false;
    const double correction = std::clamp(value / derivative, -0.5, 0.5);
    d = (d - correction * turned).normalized();
    if (std::abs(correction) < 1e-13) {
      // A tiny step can also come from a huge derivative far from a root (met from poor starts:
      // LocalSolver.ZeroesTheNaturalMapFromAnyGuess), so the misalignment itself is checked too.
      if (!sliding_candidate(W, u_free, mu, d, c) || c.tangential_velocity.dot(d) < 0.0 ||
          std::abs(misalignment(c, d)) > 1e-9 * (u_free.norm() + c.tangential_velocity.norm())) {
        return false;
      }
      impulse = c.impulse;
      return true;
    }
  }
  return false;
}

/// The sliding solution by a scan of the angle of d for sign changes of the misalignment where
/// u_T . d > 0, each bracket bisected, the first root that is a true sliding solution kept
/// (robust for any positive definite block, including strongly coupled ones). False when none is.
bool slide_by_angle_scan(const Mat3& W, const Vec3& u_free, double mu, Vec3& impulse) {
  constexpr int samples = 360;
  SlidingCandidate c;
  double best_angle = 0.0;
  bool found = false;
  double previous_angle = 0.0;
  double previous_value = 0.0;
  bool previous_valid = false;
  const double velocity_scale = u_free.norm();
  for (int k = 0; k <= samples && !found; ++k) {
    const double angle = 2.0 * std::numbers::pi * k / samples;
    const Vec2 dk(std::cos(angle), std::sin(angle));
    if (!sliding_candidate(W, u_free, mu, dk, c) || c.tangential_velocity.dot(dk) < 0.0) {
      previous_valid = false;
      continue;
    }
    const double value = misalignment(c, dk);
    if (previous_valid && (value == 0.0 || (value > 0.0) != (previous_value > 0.0))) {
      double lo = previous_angle, hi = angle, f_lo = previous_value;
      for (int bisection = 0; bisection < 60; ++bisection) {
        const double mid = 0.5 * (lo + hi);
        const Vec2 dm(std::cos(mid), std::sin(mid));
        if (!sliding_candidate(W, u_free, mu, dm, c)) break;
        const double f_mid = misalignment(c, dm);
        if ((f_mid > 0.0) == (f_lo > 0.0)) {
          lo = mid;
          f_lo = f_mid;
        } else {
          hi = mid;
        }
      }
      const double root = 0.5 * (lo + hi);
      const Vec2 dr(std::cos(root), std::sin(root));
      found = sliding_candidate(W, u_free, mu, dr, c) && c.tangential_velocity.dot(dr) >= 0.0 &&
              std::abs(misalignment(c, dr)) <= 1e-12 * (velocity_scale + c.tangential_velocity.norm());
      best_angle = root;
    }
    previous_angle = angle;
    previous_value = value;
    previous_valid = true;
  }
  const Vec2 d_best(std::cos(best_angle), std::sin(best_angle));
  if (!found || !sliding_candidate(W, u_free, mu, d_best, c)) return false;
  impulse = c.impulse;
  return true;
}

}  // namespace

LocalSolution solve_local_contact(const Mat3& W, const Vec3& u_free, double mu) {
  if (u_free.x() >= 0.0) return LocalSolution{};  // separating without any impulse: open
  // Fixed-size 3x3 inverse by cofactors: W is symmetric positive definite (H^T M^-1 H), so no
  // pivoting is needed, and it is several times cheaper than an LU factorisation.
  return solve_local_contact(W, W.inverse(), u_free, mu);
}

LocalSolution solve_local_contact(const Mat3& W, const Mat3& W_inverse, const Vec3& u_free, double mu,
                                  const Vec3& guess) {
  if (u_free.x() >= 0.0) return LocalSolution{};  // separating without any impulse: open
  return solve_from_sticking_trial(W, W_inverse, u_free, -(W_inverse * u_free), mu, guess);
}

Vec3 slide_on_coupled_block(const Mat3& W, const Mat3& W_inverse, const Vec3& u_free, double mu, const Vec3& guess) {
  Vec3 impulse;
  // A guess's slip direction is the best start when it converges: in a sweep, the contact's
  // current impulse, which the sweeps before have brought near the solution (3.5 -> 2.0 Newton
  // iterations a solve on the mixed deposit: bench/RESULTS.md, "The sweep's chain shortened").
  const double guess_tangential = tangential_norm(guess);
  if (guess_tangential > 0.0 &&
      slide_by_newton(W, u_free, mu, Vec2(-guess.y() / guess_tangential, -guess.z() / guess_tangential), impulse)) {
    return impulse;
  }
  // Else friction opposes the slip, so start from the direction opposite to the sticking trial's
  // tangential part (or the free slip direction).
  const Vec3 stick = -(W_inverse * u_free);
  const double stick_tangential = tangential_norm(stick);
  Vec2 d = stick_tangential > 0.0 ? Vec2(-stick.y() / stick_tangential, -stick.z() / stick_tangential)
                                  : Vec2(u_free.y(), u_free.z()).normalized();
  if (!d.allFinite() || d.norm() < 0.5) d = Vec2(1.0, 0.0);
  if (slide_by_newton(W, u_free, mu, d, impulse)) return impulse;
  if (slide_by_angle_scan(W, u_free, mu, impulse)) return impulse;
  // Degenerate block: fall back to the projection of the sticking impulse onto the cone.
  const double r_n = std::max(stick.x(), 0.0);
  const double scale = stick_tangential > 0.0 ? mu * r_n / stick_tangential : 0.0;
  return Vec3(r_n, scale * stick.y(), scale * stick.z());
}

}  // namespace rubble
