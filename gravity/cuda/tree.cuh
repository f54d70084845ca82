#pragma once
// Raw interface of the GPU Barnes-Hut tree (C++17, no std::span, so nvcc needs no C++20). The
// public entry point is cuda::tree_field() in gravity/cuda.hpp (gravity/cuda_backend.cpp), which
// checks the input and calls tree_field() below. Everything happens on the GPU: Morton keys, radix
// sort, the compressed octree level by level, moments bottom-up, target groups (tree_build.cu),
// then the walk and the interaction kernels (tree_walk.cu).

#include <cstddef>
#include <cstdint>
#include <vector>

namespace rubble::gravity::cuda::detail {

/// Everything tree_field() needs: host arrays and the options of gravity::Tree and GravityOptions.
struct TreeFieldInput {
  const double* positions = nullptr;  ///< 3N, the caller's order [m]
  const double* masses = nullptr;     ///< N [kg]
  std::size_t n = 0;
  double lo[3] = {0, 0, 0};  ///< corner of the particles' bounding box (Tree::build's, computed on the host)
  double extent = 0;         ///< longest side of that box [m]
  int leaf_size = 16;        ///< max particles per leaf
  int group_size = 64;       ///< max targets per walk group
  double theta = 0.5;        ///< opening angle
  bool quadrupole = true;    ///< order 2 (else monopole)
  double eps2 = 0;           ///< Plummer length squared (0: no softening)
  double G = 0;              ///< gravitational constant
};

/// Seconds spent in each part of tree_field() (host wall clock, synchronised).
struct TreeFieldTimings {
  double build_seconds = 0;     ///< keys, sort, nodes, moments, groups (device memory included)
  double walk_seconds = 0;      ///< the walk and the kernels
  double transfer_seconds = 0;  ///< copies of the particles to the GPU and of the field back
};

/// Field of all particles on all particles (self excluded), in the caller's order: acc 3N, pot N or
/// nullptr. Throws std::runtime_error on a CUDA error or when a group's node stack overflows.
void tree_field(const TreeFieldInput& input, double* acc, double* pot, TreeFieldTimings* timings);

/// One node of a tree built on the GPU, copied back (tests compare it with gravity::Tree's).
struct BuiltNode {
  double cx, cy, cz, mass, bmax, size, delta;  ///< as gravity::Tree::Node
  double lo[3], hi[3];                         ///< tight box
  double q[6];                                 ///< second moment Mxx Mxy Mxz Myy Myz Mzz
  std::uint32_t begin, count;                  ///< particle range in Morton order
  std::int32_t num_children;                   ///< 0 for a leaf
};

/// One target group of a tree built on the GPU, copied back.
struct BuiltGroup {
  double lo[3], hi[3];
  std::uint32_t begin, count;
};

/// The tree that tree_field() builds, copied back to the host: nodes (numbered as Tree::nodes()),
/// the Morton order (order[k] = input index of the k-th particle) and the groups.
struct BuiltTree {
  std::vector<BuiltNode> nodes;
  std::vector<std::uint32_t> order;
  std::vector<BuiltGroup> groups;
};
BuiltTree build_tree_for_test(const TreeFieldInput& input);

}  // namespace rubble::gravity::cuda::detail
