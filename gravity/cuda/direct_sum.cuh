#pragma once
// Raw interface of the CUDA direct sum (C++17, no std::span, so nvcc needs no C++20). The public
// API is gravity/cuda.hpp, implemented on top of this in gravity/cuda_backend.cpp.

#include <cstddef>
#include <string>

namespace rubble::gravity::cuda::detail {

/// Number of CUDA devices; 0 with the reason in *reason when none is usable (no driver, no GPU).
int device_count(std::string* reason);

/// Exact direct sum on device 0. pos: 3n, mass: n, acc: 3n, pot: n or nullptr. eps2 = Plummer
/// length squared (0: none). Throws std::runtime_error on a CUDA error.
void direct_sum(const double* pos, const double* mass, std::size_t n, double eps2, double G, double* acc, double* pot);

}  // namespace rubble::gravity::cuda::detail
