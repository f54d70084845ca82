#pragma once
// Optional CUDA backend of rubble::gravity: the exact direct sum on a GPU, in double precision.
// The functions always exist; without the backend (no CUDA toolkit at configure time) or without
// a GPU at run time, available() is false and direct_sum() throws BackendUnavailable.

#include <span>
#include <string>

#include "gravity/gravity.hpp"

namespace rubble::gravity::cuda {

/// True when the library was built with the CUDA backend (nvcc found at configure time).
bool compiled();

/// Number of CUDA devices usable now (0 without the backend, without a driver or without a GPU).
int device_count();

/// compiled() && device_count() > 0.
bool available();

/// Why the backend cannot run here (empty when available()).
std::string unavailable_reason();

/// Exact direct sum on device 0: same conventions and results (up to rounding: the GPU sums each
/// target in index order with fused multiply-adds) as rubble::gravity::direct_sum(). Throws
/// BackendUnavailable (a GravityError) when !available(), GravityError on a CUDA error.
/// compute_field() with Backend::cuda and Method::direct calls it.
void direct_sum(const GravityOptions& options, std::span<const double> positions, std::span<const double> masses,
                std::span<double> accelerations, std::span<double> potential);

}  // namespace rubble::gravity::cuda
