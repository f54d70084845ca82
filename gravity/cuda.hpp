#pragma once
// Optional CUDA backend of rubble::gravity: the exact direct sum and the Barnes-Hut tree walk on a
// GPU, in double precision. The functions always exist; without the backend (no CUDA toolkit at
// configure time) or without a GPU at run time, available() is false and direct_sum() and
// tree_field() throw BackendUnavailable.

#include <span>
#include <string>

#include "gravity/cuda/tree.cuh"
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

/// Barnes-Hut field on device 0, built and walked there: the same tree as gravity::Tree::build
/// (options.leaf_size, options.group_size: the same Morton order, nodes, moments to the last bit and
/// groups), walked with the CPU tree's opening criterion in double precision, so both accept the
/// same nodes and make the same approximation (results differ by rounding: summation order, the
/// CPU's approximate 1/sqrt). Same run to run. options.precision must be double (single-precision
/// kernels are a CPU option). Returns build_seconds (GPU build), walk_seconds (GPU walk) and
/// transfer_seconds (the particles up, the field back). Throws BackendUnavailable when
/// !available(), GravityError on bad input or a CUDA error. compute_field() with Backend::cuda and
/// Method::tree calls it.
FieldTimings tree_field(const GravityOptions& options, std::span<const double> positions,
                        std::span<const double> masses, std::span<double> accelerations, std::span<double> potential);

/// tree_field() for compute_field(), which has already checked the input (validate()) and the
/// backend (require_backend()): no second pass over the particles.
FieldTimings tree_field_checked(const GravityOptions& options, std::span<const double> positions,
                                std::span<const double> masses, std::span<double> accelerations,
                                std::span<double> potential);

/// The tree that tree_field() builds on device 0 (options.leaf_size, group_size, theta), copied
/// back: for tests that compare it with gravity::Tree. Throws like tree_field().
detail::BuiltTree built_tree(const GravityOptions& options, std::span<const double> positions,
                             std::span<const double> masses);

}  // namespace rubble::gravity::cuda
