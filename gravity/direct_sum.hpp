#pragma once
// Exact O(N^2) pairwise sum (the reference the tree is checked against).

#include <cstddef>
#include <span>

#include "gravity/gravity.hpp"

namespace rubble::gravity {

/// Exact field of all particles on all particles (self excluded). Same array conventions as
/// compute_field(); options.method/theta/order/leaf_size are ignored. OpenMP over targets, each
/// target summed in index order by the SIMD kernel: results do not depend on the thread count.
void direct_sum(const GravityOptions& options, std::span<const double> positions, std::span<const double> masses,
                std::span<double> accelerations, std::span<double> potential);

/// Exact field on a subset of the particles: for k = 0..K-1, target i = targets[k] receives the
/// field of all particles j != i in accelerations[3k..3k+2] and potential[k] (potential may be
/// empty). Used to check the tree on a random subset when N is too large for a full direct sum.
void direct_sum_targets(const GravityOptions& options, std::span<const double> positions,
                        std::span<const double> masses, std::span<const std::size_t> targets,
                        std::span<double> accelerations, std::span<double> potential);

}  // namespace rubble::gravity
