// gravity/cuda.hpp on top of the raw CUDA entry points (built only with the CUDA backend).
#include <stdexcept>

#include "gravity/cuda.hpp"
#include "gravity/cuda/direct_sum.cuh"

namespace rubble::gravity::cuda {

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
  std::string reason;
  if (detail::device_count(&reason) == 0) throw BackendUnavailable("CUDA backend: " + reason);
  const double eps = options.softening.kind == Softening::Kind::plummer ? options.softening.length : 0.0;
  try {
    detail::direct_sum(positions.data(), masses.data(), masses.size(), eps * eps, options.G, accelerations.data(),
                       potential.empty() ? nullptr : potential.data());
  } catch (const std::runtime_error& e) {
    throw GravityError(e.what());
  }
}

}  // namespace rubble::gravity::cuda
