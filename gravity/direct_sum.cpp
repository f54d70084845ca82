#include "gravity/direct_sum.hpp"

#include <cmath>
#include <string>
#include <vector>

#include "gravity/kernels.hpp"

namespace rubble::gravity {
namespace {

/// Sources as structure of arrays (the input is x0,y0,z0,x1,...): one O(N) copy makes the O(N^2)
/// inner loop unit-stride and vectorizable.
struct SoA {
  std::vector<double> x, y, z, m;
  SoA(std::span<const double> positions, std::span<const double> masses)
      : x(masses.size()), y(masses.size()), z(masses.size()), m(masses.begin(), masses.end()) {
    for (std::size_t i = 0; i < masses.size(); ++i) {
      x[i] = positions[3 * i];
      y[i] = positions[3 * i + 1];
      z[i] = positions[3 * i + 2];
    }
  }
};

double eps2_of(const GravityOptions& options) {
  return options.softening.kind == Softening::Kind::plummer ? options.softening.length * options.softening.length : 0.0;
}

/// Field on particle i (self excluded). With softening the kernel includes the self term
/// m_i / eps in the potential (its acceleration is zero since r = 0): it is removed here.
detail::Accum field_on(const SoA& s, std::size_t i, double eps2) {
  detail::Accum acc;
  detail::p2p(s.x.data(), s.y.data(), s.z.data(), s.m.data(), s.m.size(), s.x[i], s.y[i], s.z[i], eps2, acc);
  if (eps2 > 0.0) acc.phi -= s.m[i] / std::sqrt(eps2);
  return acc;
}

}  // namespace

void direct_sum(const GravityOptions& options, std::span<const double> positions, std::span<const double> masses,
                std::span<double> accelerations, std::span<double> potential) {
  GravityOptions o = options;
  o.method = Method::direct;
  validate(o, positions, masses, accelerations, potential);
  const SoA s(positions, masses);
  const double eps2 = eps2_of(options);
  const double G = options.G;
  const auto n = static_cast<std::ptrdiff_t>(masses.size());
  const bool with_potential = !potential.empty();
  // Each target is independent and summed in a fixed order: any schedule gives the same bits.
#pragma omp parallel for schedule(static) if (n >= 256)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto u = static_cast<std::size_t>(i);
    const detail::Accum acc = field_on(s, u, eps2);
    accelerations[3 * u] = -G * acc.ax;
    accelerations[3 * u + 1] = -G * acc.ay;
    accelerations[3 * u + 2] = -G * acc.az;
    if (with_potential) potential[u] = -G * acc.phi;
  }
}

void direct_sum_targets(const GravityOptions& options, std::span<const double> positions,
                        std::span<const double> masses, std::span<const std::size_t> targets,
                        std::span<double> accelerations, std::span<double> potential) {
  GravityOptions o = options;
  o.method = Method::direct;
  const std::size_t k = targets.size();
  validate_particles(o, positions, masses);
  if (accelerations.size() != 3 * k)
    throw GravityError("direct_sum_targets: accelerations must hold 3 * targets.size() values");
  if (!potential.empty() && potential.size() != k)
    throw GravityError("direct_sum_targets: potential must be empty or hold targets.size() values");
  for (std::size_t t : targets)
    if (t >= masses.size())
      throw GravityError("direct_sum_targets: target index " + std::to_string(t) + " out of range");
  const SoA s(positions, masses);
  const double eps2 = eps2_of(options);
  const double G = options.G;
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t q = 0; q < static_cast<std::ptrdiff_t>(k); ++q) {
    const auto u = static_cast<std::size_t>(q);
    const detail::Accum acc = field_on(s, targets[u], eps2);
    accelerations[3 * u] = -G * acc.ax;
    accelerations[3 * u + 1] = -G * acc.ay;
    accelerations[3 * u + 2] = -G * acc.az;
    if (!potential.empty()) potential[u] = -G * acc.phi;
  }
}

}  // namespace rubble::gravity
