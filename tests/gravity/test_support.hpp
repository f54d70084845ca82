#pragma once
// Shared helpers for the gravity tests: particle samplers and error statistics.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace rubble::gravity::testing {

/// Problem sizes shrink under sanitizers (RUBBLE_GRAVITY_TEST_SMALL), where code runs ~20x slower.
#ifdef RUBBLE_GRAVITY_TEST_SMALL
constexpr std::size_t kScale = 5;
#else
constexpr std::size_t kScale = 1;
#endif

struct Particles {
  std::vector<double> pos;   // 3N
  std::vector<double> mass;  // N
  std::size_t size() const { return mass.size(); }
};

/// Random unit vector times r, appended to pos.
inline void push_on_sphere(std::mt19937_64& rng, double r, std::vector<double>& pos) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double cz = 2.0 * u(rng) - 1.0, ph = 2.0 * M_PI * u(rng);
  const double sz = std::sqrt(1.0 - cz * cz);
  pos.push_back(r * sz * std::cos(ph));
  pos.push_back(r * sz * std::sin(ph));
  pos.push_back(r * cz);
}

/// n equal masses (total mass total_mass) uniformly distributed in a ball of radius radius.
inline Particles uniform_sphere(std::size_t n, double radius, double total_mass, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Particles p;
  p.mass.assign(n, total_mass / static_cast<double>(n));
  for (std::size_t i = 0; i < n; ++i) push_on_sphere(rng, radius * std::cbrt(u(rng)), p.pos);
  return p;
}

/// Plummer sphere (scale radius a, cut at 20 a) by inverting M(<r)/M = r^3 / (r^2 + a^2)^{3/2}.
inline Particles plummer_sphere(std::size_t n, double a, double total_mass, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Particles p;
  p.mass.assign(n, total_mass / static_cast<double>(n));
  for (std::size_t i = 0; i < n; ++i) {
    double r;
    do {
      r = a / std::sqrt(std::pow(u(rng), -2.0 / 3.0) - 1.0);
    } while (!(r < 20.0 * a));
    push_on_sphere(rng, r, p.pos);
  }
  return p;
}

struct ErrorStats {
  double median = 0, p99 = 0, max = 0;
};

/// Per-particle |a - a_ref| / |a_ref| summarised as median / 99th percentile / max.
inline ErrorStats relative_errors(const std::vector<double>& a, const std::vector<double>& ref) {
  std::vector<double> e(ref.size() / 3);
  for (std::size_t i = 0; i < e.size(); ++i) {
    double d2 = 0, r2 = 0;
    for (int c = 0; c < 3; ++c) {
      d2 += (a[3 * i + c] - ref[3 * i + c]) * (a[3 * i + c] - ref[3 * i + c]);
      r2 += ref[3 * i + c] * ref[3 * i + c];
    }
    e[i] = std::sqrt(d2 / r2);
  }
  std::sort(e.begin(), e.end());
  ErrorStats s;
  s.median = e[e.size() / 2];
  s.p99 = e[static_cast<std::size_t>(0.99 * static_cast<double>(e.size() - 1))];
  s.max = e.back();
  return s;
}

}  // namespace rubble::gravity::testing
