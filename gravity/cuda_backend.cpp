// gravity/cuda.hpp on top of the raw CUDA entry points (built only with the CUDA backend).
#include <array>
#include <stdexcept>

#include "gravity/cuda.hpp"
#include "gravity/cuda/direct_sum.cuh"
#include "gravity/cuda/tree.cuh"
#include "gravity/tree.hpp"

namespace rubble::gravity::cuda {
namespace {

double softening_length(const GravityOptions& options) {
  return options.softening.kind == Softening::Kind::plummer ? options.softening.length : 0.0;
}

void require_device() {
  std::string reason;
  if (detail::device_count(&reason) == 0) throw BackendUnavailable("CUDA backend: " + reason);
}

}  // namespace

bool compiled() { return true; }

int device_count() { return detail::device_count(nullptr); }

bool available() { return device_count() > 0; }

std::string unavailable_reason() {
  std::string reason;
  return detail::device_count(&reason) > 0 ? std::string() : reason;
}

void direct_sum(const GravityOptions& options, std::span<const double> positions, std::span<const double> masses,
                std::span<double> accelerations, std::span<double> potential) {
  GravityOptions o = options;
  o.method = Method::direct;
  validate(o, positions, masses, accelerations, potential);
  require_device();
  const double eps = softening_length(options);
  try {
    detail::direct_sum(positions.data(), masses.data(), masses.size(), eps * eps, options.G, accelerations.data(),
                       potential.empty() ? nullptr : potential.data());
  } catch (const std::runtime_error& e) {
    throw GravityError(e.what());
  }
}

namespace {

/// The GPU tree's input: the particles, their bounding box and the options.
detail::TreeFieldInput tree_input(const GravityOptions& options, std::span<const double> positions,
                                  std::span<const double> masses) {
  detail::TreeFieldInput input;
  input.positions = positions.data();
  input.masses = masses.data();
  input.n = masses.size();
  if (input.n > 0) {
    std::array<double, 3> lo{};
    Tree::bounding_cube(positions, lo, input.extent);
    for (std::size_t d = 0; d < 3; ++d) input.lo[d] = lo[d];
  }
  input.leaf_size = options.leaf_size;
  input.group_size = options.group_size;
  input.theta = options.theta;
  input.quadrupole = options.order == 2;
  const double eps = softening_length(options);
  input.eps2 = eps * eps;
  input.G = options.G;
  return input;
}

}  // namespace

FieldTimings tree_field(const GravityOptions& options, std::span<const double> positions,
                        std::span<const double> masses, std::span<double> accelerations, std::span<double> potential) {
  GravityOptions o = options;
  o.method = Method::tree;
  validate(o, positions, masses, accelerations, potential);
  if (options.precision != KernelPrecision::double_precision)
    throw BackendUnavailable(
        "CUDA backend: the GPU tree computes in double precision only (precision single is a "
        "CPU option)");
  require_device();
  return tree_field_checked(options, positions, masses, accelerations, potential);
}

FieldTimings tree_field_checked(const GravityOptions& options, std::span<const double> positions,
                                std::span<const double> masses, std::span<double> accelerations,
                                std::span<double> potential) {
  detail::TreeFieldTimings walk;
  try {
    detail::tree_field(tree_input(options, positions, masses), accelerations.data(),
                       potential.empty() ? nullptr : potential.data(), &walk);
  } catch (const std::runtime_error& e) {
    throw GravityError(e.what());
  }
  FieldTimings timings;
  timings.build_seconds = walk.build_seconds;
  timings.walk_seconds = walk.walk_seconds;
  timings.transfer_seconds = walk.transfer_seconds;
  return timings;
}

detail::BuiltTree built_tree(const GravityOptions& options, std::span<const double> positions,
                             std::span<const double> masses) {
  GravityOptions o = options;
  o.method = Method::tree;
  validate_particles(o, positions, masses);
  require_device();
  try {
    return detail::build_tree_for_test(tree_input(options, positions, masses));
  } catch (const std::runtime_error& e) {
    throw GravityError(e.what());
  }
}

}  // namespace rubble::gravity::cuda
