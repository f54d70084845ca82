#pragma once
// Raw interface of the GPU tree walk (C++17, no std::span, so nvcc needs no C++20). The tree is
// built on the host (gravity::Tree: Morton sort, compressed octree, moments, target groups) and
// handed over as plain arrays; the walk and the interaction kernels run on the GPU. The public
// entry point is cuda::tree_field() in gravity/cuda.hpp (gravity/cuda_backend.cpp).

#include <cstddef>
#include <cstdint>

namespace rubble::gravity::cuda::detail {

/// One tree node as the GPU walk reads it (128 bytes: one node, one aligned load sequence).
struct alignas(16) WalkNode {
  double cx, cy, cz;           ///< centre of mass [m]
  double mass;                 ///< total mass [kg]
  double r_open2;              ///< squared opening radius, Tree::opening_radius2 [m^2]
  double q[6];                 ///< second moment Mxx Mxy Mxz Myy Myz Mzz about the centre [kg m^2]
  std::uint32_t begin, count;  ///< particle range in Morton order
  std::int32_t first_child;    ///< index of the first child, -1 for a leaf
  std::int32_t num_children;   ///< number of children (contiguous from first_child)
  double pad[3];               ///< to 128 bytes
};
static_assert(sizeof(WalkNode) == 128, "WalkNode is one 128-byte record");

/// One group of targets that walks the tree together (Tree::Group).
struct WalkGroup {
  double lo[3], hi[3];         ///< tight box of the targets [m]
  std::uint32_t begin, count;  ///< target range in Morton order
};

/// Everything the walk reads, host pointers.
struct TreeWalkInput {
  std::size_t num_particles = 0;
  const double *x = nullptr, *y = nullptr, *z = nullptr, *m = nullptr;  ///< Morton order
  std::size_t num_nodes = 0;
  const WalkNode* nodes = nullptr;  ///< root first, children after their parent
  std::size_t num_groups = 0;
  const WalkGroup* groups = nullptr;
  bool quadrupole = true;  ///< order 2 (else monopole)
  double eps2 = 0;         ///< Plummer length squared (0: no softening)
  double G = 0;            ///< gravitational constant
};

/// Seconds spent in each part of tree_walk() (host wall clock, synchronised).
struct TreeWalkTimings {
  double upload_seconds = 0;    ///< allocation and host-to-device copies
  double kernel_seconds = 0;    ///< the walk and the kernels
  double download_seconds = 0;  ///< device-to-host copies
};

/// Field of all particles on all particles (self excluded), in Morton order: acc 3N, pot N or
/// nullptr. Throws std::runtime_error on a CUDA error or when a group's node stack overflows.
void tree_walk(const TreeWalkInput& input, double* acc, double* pot, TreeWalkTimings* timings);

}  // namespace rubble::gravity::cuda::detail
