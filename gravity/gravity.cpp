#include "gravity/gravity.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "gravity/cuda.hpp"
#include "gravity/direct_sum.hpp"
#include "gravity/tree.hpp"

namespace rubble::gravity {

std::string to_string(Method method) {
  switch (method) {
    case Method::direct:
      return "direct";
    case Method::tree:
      return "tree";
  }
  return "unknown";
}

std::string to_string(Backend backend) {
  switch (backend) {
    case Backend::cpu:
      return "cpu";
    case Backend::cuda:
      return "cuda";
  }
  return "unknown";
}

std::string to_string(KernelPrecision precision) {
  switch (precision) {
    case KernelPrecision::double_precision:
      return "double";
    case KernelPrecision::single_precision:
      return "single";
  }
  return "unknown";
}

std::string backend_unavailable_reason(const GravityOptions& options) {
  if (options.backend == Backend::cpu) return {};
  std::string reason;
  // The GPU tree's kernels are double only. Said first, since a GPU would not help.
  if (options.method == Method::tree && options.precision != KernelPrecision::double_precision)
    reason = "the GPU tree computes in double precision only (precision single is a CPU option)";
  if (!cuda::available()) {
    if (!reason.empty()) reason += "; ";
    reason += cuda::unavailable_reason();
  }
  return reason;
}

void require_backend(const GravityOptions& options) {
  const std::string reason = backend_unavailable_reason(options);
  if (!reason.empty()) throw BackendUnavailable("backend " + to_string(options.backend) + ": " + reason);
}

namespace {

/// Adds x * 0 over x[0, n) to zero_sum: it stays 0 exactly when every value is finite (x * 0 is 0
/// for a finite x and NaN for an infinity or a NaN, in any order of summation). Eight independent
/// accumulators, so that the loop runs at memory speed, not at the latency of one chain of
/// additions. least (when given) becomes the least value.
void probe_values(const double* x, std::size_t n, double& zero_sum, double* least) {
  double sum[8] = {}, low[8] = {};
  if (least) std::fill(low, low + 8, *least);
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8)
    for (std::size_t k = 0; k < 8; ++k) sum[k] += x[i + k] * 0.0;
  for (; i < n; ++i) sum[0] += x[i] * 0.0;
  for (std::size_t k = 0; k < 8; ++k) zero_sum += sum[k];
  if (!least) return;
  for (i = 0; i + 8 <= n; i += 8)
    for (std::size_t k = 0; k < 8; ++k) low[k] = std::min(low[k], x[i + k]);
  for (; i < n; ++i) low[0] = std::min(low[0], x[i]);
  *least = *std::min_element(low, low + 8);
}

/// The common case of validate_particles in one pass at memory speed, on all threads for large N
/// (the element-by-element checks were a third of a GPU tree evaluation at 10^7 particles). The
/// answer does not depend on the threads: a sum of zeros is zero and NaN stays NaN in any order.
bool all_finite_and_masses_non_negative(std::span<const double> positions, std::span<const double> masses) {
  constexpr std::size_t kChunk = std::size_t{1} << 16;  // masses per task
  const std::size_t n = masses.size(), chunks = (n + kChunk - 1) / kChunk;
  double zero_sum = 0.0, least_mass = 0.0;
  if (chunks <= 4) {  // no OpenMP region for small inputs: it costs what the pass does at N ~ 100
    probe_values(positions.data(), 3 * n, zero_sum, nullptr);
    probe_values(masses.data(), n, zero_sum, &least_mass);
    return zero_sum == 0.0 && least_mass >= 0.0;
  }
#pragma omp parallel for reduction(+ : zero_sum) reduction(min : least_mass)
  for (std::ptrdiff_t c = 0; c < static_cast<std::ptrdiff_t>(chunks); ++c) {
    const std::size_t b = static_cast<std::size_t>(c) * kChunk, e = std::min(n, b + kChunk);
    probe_values(positions.data() + 3 * b, 3 * (e - b), zero_sum, nullptr);
    probe_values(masses.data() + b, e - b, zero_sum, &least_mass);
  }
  return zero_sum == 0.0 && least_mass >= 0.0;
}

}  // namespace

void validate_particles(const GravityOptions& options, std::span<const double> positions,
                        std::span<const double> masses) {
  if (!std::isfinite(options.G)) throw GravityError("G must be finite");
  if (options.softening.kind == Softening::Kind::plummer &&
      (!(options.softening.length >= 0) || !std::isfinite(options.softening.length)))
    throw GravityError("softening length must be finite and >= 0");
  if (positions.size() != 3 * masses.size())
    throw GravityError("positions must hold 3 values per mass (got " + std::to_string(positions.size()) +
                       " values for " + std::to_string(masses.size()) + " masses)");
  if (all_finite_and_masses_non_negative(positions, masses)) return;
  for (std::size_t i = 0; i < masses.size(); ++i) {  // which one, for the message
    if (!std::isfinite(masses[i]) || masses[i] < 0)
      throw GravityError("mass " + std::to_string(i) + " is not a finite number >= 0");
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(positions[3 * i + d])) throw GravityError("position " + std::to_string(i) + " is not finite");
  }
}

void validate(const GravityOptions& options, std::span<const double> positions, std::span<const double> masses,
              std::span<const double> accelerations, std::span<const double> potential) {
  if (options.method == Method::tree) {
    if (!(options.theta > 0) || !std::isfinite(options.theta)) throw GravityError("theta must be a finite number > 0");
    if (options.order != 1 && options.order != 2) throw GravityError("order must be 1 (monopole) or 2 (quadrupole)");
    if (options.leaf_size < 1) throw GravityError("leaf_size must be >= 1");
    if (options.group_size < 1) throw GravityError("group_size must be >= 1");
  }
  validate_particles(options, positions, masses);
  if (accelerations.size() != positions.size())
    throw GravityError("accelerations must hold 3N values (" + std::to_string(positions.size()) + "), got " +
                       std::to_string(accelerations.size()));
  if (!potential.empty() && potential.size() != masses.size())
    throw GravityError("potential must be empty or hold N values (" + std::to_string(masses.size()) + "), got " +
                       std::to_string(potential.size()));
}

FieldWorkspace::FieldWorkspace() = default;
FieldWorkspace::~FieldWorkspace() = default;
FieldWorkspace::FieldWorkspace(const FieldWorkspace&) {}
FieldWorkspace::FieldWorkspace(FieldWorkspace&&) noexcept = default;
FieldWorkspace& FieldWorkspace::operator=(const FieldWorkspace& other) {
  if (this != &other) tree.reset();
  return *this;
}
FieldWorkspace& FieldWorkspace::operator=(FieldWorkspace&&) noexcept = default;

FieldTimings compute_field(const GravityOptions& options, std::span<const double> positions,
                           std::span<const double> masses, std::span<double> accelerations,
                           std::span<double> potential) {
  FieldWorkspace workspace;
  return compute_field(options, positions, masses, accelerations, potential, workspace);
}

FieldTimings compute_field(const GravityOptions& options, std::span<const double> positions,
                           std::span<const double> masses, std::span<double> accelerations, std::span<double> potential,
                           FieldWorkspace& workspace) {
  validate(options, positions, masses, accelerations, potential);
  require_backend(options);
  FieldTimings t;
  if (options.backend == Backend::cuda && options.method == Method::tree)
    return cuda::tree_field_checked(options, positions, masses, accelerations, potential);
  if (options.backend == Backend::cuda) {
    const auto t0 = std::chrono::steady_clock::now();
    cuda::direct_sum(options, positions, masses, accelerations, potential);
    t.walk_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return t;
  }
  if (options.method == Method::direct) {
    const auto t0 = std::chrono::steady_clock::now();
    direct_sum(options, positions, masses, accelerations, potential);
    t.walk_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return t;
  }
  std::unique_ptr<Tree>& tree = workspace.tree;
  if (!tree || tree->leaf_size() != options.leaf_size || tree->group_size() != options.group_size)
    tree = std::make_unique<Tree>(options.leaf_size, options.group_size);
  t.build_seconds = tree->build(positions, masses);
  t.walk_seconds = tree->evaluate(options, accelerations, potential);
  return t;
}

}  // namespace rubble::gravity
