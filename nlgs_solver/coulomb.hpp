#pragma once
// The Coulomb cone and the natural-map residual of the Signorini-Coulomb law
// (De Saxcé and Feng 1998; the form FCLib states, Acary et al. 2014).
// Local vectors are ordered (normal, t, s); r_n >= 0 pushes the bodies apart.
#include <cmath>

#include "core/math.hpp"

namespace rubble {

/// Length of the tangential part (t, s) of a local vector. Plain sqrt: std::hypot's overflow
/// guard costs more than the rest of a local solve, and impulses and velocities never come near
/// 1e154.
inline double tangential_norm(const Vec3& x) { return std::sqrt(x.y() * x.y() + x.z() * x.z()); }

/// Euclidean projection of x onto the cone K_mu = {||x_T|| <= mu x_n}.
inline Vec3 project_onto_coulomb_cone(const Vec3& x, double mu) {
  const double normal = x.x();
  const double tangential_squared = x.y() * x.y() + x.z() * x.z();
  // Inside K; normal >= 0 matters for mu = 0 only, whose K is the half-line x_T = 0, x_n >= 0
  // (without it (-1, 0, 0) counted as inside, and an open frictionless contact with no tangential
  // velocity at all had the natural map u_n instead of 0).
  if (normal >= 0.0 && tangential_squared <= (mu * normal) * (mu * normal)) return x;
  const double tangential = std::sqrt(tangential_squared);
  if (mu * tangential <= -normal) return Vec3::Zero();  // inside the polar cone -K*
  const double projected_normal = (normal + mu * tangential) / (1.0 + mu * mu);
  const double scale = mu * projected_normal / tangential;
  return Vec3(projected_normal, scale * x.y(), scale * x.z());
}

/// Natural map of one contact: F = r - P_K(r - u_hat), u_hat = u + [mu ||u_T||, 0, 0] (De Saxcé).
/// F = 0 exactly when (r, u) satisfies Signorini + Coulomb. `rho` scales r first (F is then in
/// velocity units when rho = W_nn, the contact's normal compliance).
inline Vec3 natural_map(const Vec3& impulse, const Vec3& velocity, double mu, double rho = 1.0) {
  const Vec3 r = rho * impulse;
  Vec3 u_hat = velocity;
  u_hat.x() += mu * tangential_norm(velocity);
  return r - project_onto_coulomb_cone(r - u_hat, mu);
}

}  // namespace rubble
