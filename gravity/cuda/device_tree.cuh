#pragma once
// Device-side types shared by tree_build.cu and tree_walk.cu (included by .cu files only).

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "gravity/cuda/tree.cuh"

namespace rubble::gravity::cuda::detail {

/// Throws std::runtime_error("CUDA tree: WHAT: <the CUDA error>") unless e is cudaSuccess.
inline void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA tree: ") + what + ": " + cudaGetErrorString(e));
}

/// Device memory released on scope exit; movable, so that a DeviceTree can own its arrays.
template <class T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(std::size_t n) { allocate(n); }
  ~DeviceBuffer() { release(); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& other) noexcept : ptr_(other.ptr_), size_(other.size_) { other.ptr_ = nullptr; }
  DeviceBuffer& operator=(DeviceBuffer&& other) noexcept {
    if (this != &other) {
      release();
      ptr_ = other.ptr_, size_ = other.size_;
      other.ptr_ = nullptr;
    }
    return *this;
  }
  /// Replaces the contents with n uninitialised elements.
  void allocate(std::size_t n) {
    release();
    if (n > 0) check(cudaMalloc(&ptr_, n * sizeof(T)), "cudaMalloc");
    size_ = n;
  }
  T* get() const { return ptr_; }
  std::size_t size() const { return size_; }

 private:
  void release() {
    if (ptr_) cudaFree(ptr_);
    ptr_ = nullptr;
    size_ = 0;
  }
  T* ptr_ = nullptr;
  std::size_t size_ = 0;
};

/// One particle for the kernels: position and mass in one 32-byte record.
struct alignas(32) Particle {
  double x, y, z, m;
};

/// One tree node as the walk reads it (128 bytes).
struct alignas(16) WalkNode {
  double cx, cy, cz;           ///< centre of mass [m]
  double mass;                 ///< total mass [kg]
  double r_open2;              ///< squared opening radius max(l / theta + delta, b_max)^2 [m^2]
  double q[6];                 ///< second moment Mxx Mxy Mxz Myy Myz Mzz about the centre [kg m^2]
  std::uint32_t begin, count;  ///< particle range in Morton order
  std::int32_t first_child;    ///< index of the first child, -1 for a leaf
  std::int32_t num_children;   ///< number of children (contiguous from first_child)
  double pad[3];               ///< to 128 bytes
};
static_assert(sizeof(WalkNode) == 128, "WalkNode is one 128-byte record");

/// A tree on the GPU, ready to walk: particles in Morton order, nodes (root first, children
/// contiguous after their parent), target groups, and the permutation back to the caller's order.
struct DeviceTree {
  DeviceBuffer<Particle> particles;   ///< Morton order
  DeviceBuffer<std::uint32_t> order;  ///< order[k]: caller index of particles[k]
  DeviceBuffer<WalkNode> nodes;
  DeviceBuffer<BuiltGroup> groups;
  /// Each node's full record (box, b_max, size, delta), kept for build_tree_for_test().
  DeviceBuffer<BuiltNode> built_nodes;
};

/// Builds the tree of input's particles, already on the GPU (positions 3N, masses N), with
/// input's leaf_size, group_size, theta and bounding box. The same tree as gravity::Tree::build:
/// the same Morton order, the same node array (same numbering) with the same moments to the last
/// bit (tree_build.cu is compiled without fused multiply-adds, as the host code is), the same
/// groups (in another order).
DeviceTree build_tree(const TreeFieldInput& input, const double* positions, const double* masses);

}  // namespace rubble::gravity::cuda::detail
