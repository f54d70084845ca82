#include "gravity/direct_sum.hpp"

#include <algorithm>
#include <array>
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

/// Targets whose fields one task sums: p2p_targets reads the sources once for every four.
constexpr std::size_t kTargetsPerTask = 4;

/// Fields on the targets s[index[0]], ..., s[index[count - 1]] (count <= kTargetsPerTask), self
/// excluded. With softening the kernel includes the self term m_i / eps in the potential (its
/// acceleration is zero since r = 0): it is removed here.
void fields_on(const SoA& s, const std::size_t* index, std::size_t count, double eps2, detail::Accum* acc) {
  std::array<double, kTargetsPerTask> x{}, y{}, z{};
  for (std::size_t t = 0; t < count; ++t) {
    x[t] = s.x[index[t]], y[t] = s.y[index[t]], z[t] = s.z[index[t]];
    acc[t] = {};
  }
  detail::p2p_targets(s.x.data(), s.y.data(), s.z.data(), s.m.data(), s.m.size(), x.data(), y.data(), z.data(), count,
                      eps2, acc);
  if (eps2 > 0.0)
    for (std::size_t t = 0; t < count; ++t) acc[t].phi -= s.m[index[t]] / std::sqrt(eps2);
}

/// The blocks of kTargetsPerTask targets that `count` targets make.
std::ptrdiff_t blocks_of(std::size_t count) {
  return static_cast<std::ptrdiff_t>((count + kTargetsPerTask - 1) / kTargetsPerTask);
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
  const std::ptrdiff_t blocks = blocks_of(masses.size());
  const bool with_potential = !potential.empty();
  // Each target is independent and summed in a fixed order: any schedule gives the same bits.
#pragma omp parallel for schedule(static) if (n >= 256)
  for (std::ptrdiff_t b = 0; b < blocks; ++b) {
    std::array<std::size_t, kTargetsPerTask> index{};
    const std::size_t first = static_cast<std::size_t>(b) * kTargetsPerTask;
    const std::size_t count = std::min(kTargetsPerTask, masses.size() - first);
    for (std::size_t t = 0; t < count; ++t) index[t] = first + t;
    std::array<detail::Accum, kTargetsPerTask> acc;
    fields_on(s, index.data(), count, eps2, acc.data());
    for (std::size_t t = 0; t < count; ++t) {
      const std::size_t u = first + t;
      accelerations[3 * u] = -G * acc[t].ax;
      accelerations[3 * u + 1] = -G * acc[t].ay;
      accelerations[3 * u + 2] = -G * acc[t].az;
      if (with_potential) potential[u] = -G * acc[t].phi;
    }
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
  const std::ptrdiff_t blocks = blocks_of(k);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t b = 0; b < blocks; ++b) {
    const std::size_t first = static_cast<std::size_t>(b) * kTargetsPerTask;
    const std::size_t count = std::min(kTargetsPerTask, k - first);
    std::array<detail::Accum, kTargetsPerTask> acc;
    fields_on(s, targets.data() + first, count, eps2, acc.data());
    for (std::size_t t = 0; t < count; ++t) {
      const std::size_t u = first + t;
      accelerations[3 * u] = -G * acc[t].ax;
      accelerations[3 * u + 1] = -G * acc[t].ay;
      accelerations[3 * u + 2] = -G * acc[t].az;
      if (!potential.empty()) potential[u] = -G * acc[t].phi;
    }
  }
}

}  // namespace rubble::gravity
