#pragma once
// rubble works in SI units throughout: metre, kilogram, second, newton, N·s for impulses,
// rad and rad/s for angles and angular velocities. Scene files use the same units.

namespace rubble::units {

/// Newtonian constant of gravitation, m^3 kg^-1 s^-2 (the accretion study's value).
inline constexpr double gravitational_constant = 6.674e-11;
/// Standard gravity at the Earth's surface, m/s^2 (a default for lab scenes).
inline constexpr double standard_gravity = 9.80665;

}  // namespace rubble::units
