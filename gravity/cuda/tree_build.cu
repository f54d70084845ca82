// The Barnes-Hut tree built on the GPU: the same tree as gravity::Tree::build (gravity/tree.cpp,
// gravity/README.md "Barnes-Hut tree"), in parallel.
//   1. Morton keys of the particles in their bounding cube (63 bits), one thread a particle.
//   2. Stable radix sort of (key, index) (CUB's DeviceRadixSort: least significant digit first, so
//      the same permutation as the host's stable sort), particles gathered in that order.
//   3. The compressed octree, level by level: each node of a level finds the octal digit at which
//      its keys first differ and its children's ranges by binary search (the host's
//      partition_point), a prefix sum over the level places the children contiguously.
//   4. Moments bottom-up, one level at a time from the deepest: the host's leaf_moments and
//      parent_moments, expression for expression. This file is compiled without fused
//      multiply-adds (-fmad=false, gravity/CMakeLists.txt), so every node equals the host's to
//      the last bit (test Cuda.TreeBuiltOnTheGpuIsTheHostTree).
//   5. Target groups: each node with more than group_size particles packs its children into
//      groups as the host's collect_groups does; a prefix sum places them.
//   6. The nodes renumbered as the host numbers them (depth first), from subtree sizes and
//      preorder positions: the same node array as Tree::nodes().
// The parallel construction level by level follows the idea of Karras (2012, "Maximizing
// parallelism in the construction of BVHs, octrees, and k-d trees", High Performance Graphics):
// every node of a level is split independently from the sorted keys alone.

#include <cub/cub.cuh>

#include <algorithm>
#include <vector>

#include "gravity/cuda/device_tree.cuh"
#include "gravity/morton.hpp"

namespace rubble::gravity::cuda::detail {
namespace {

constexpr double kBmaxSafety = 1.0 + 1e-12;  // as tree.cpp
constexpr int kBlock = 256;

int blocks_for(std::size_t n) { return static_cast<int>((n + kBlock - 1) / kBlock); }

__global__ void morton_keys(const double* pos, int n, double lox, double loy, double loz, double scale,
                            std::uint64_t* keys, std::uint32_t* index) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const double lo[3] = {lox, loy, loz};
  keys[i] = morton::key(pos + 3 * static_cast<std::size_t>(i), lo, scale);
  index[i] = static_cast<std::uint32_t>(i);
}

__global__ void gather_particles(const double* pos, const double* mass, const std::uint32_t* order, int n,
                                 Particle* out) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const std::uint32_t i = order[k];
  out[k] = Particle{pos[3 * i], pos[3 * i + 1], pos[3 * i + 2], mass[i]};
}

/// The node topology while it is built, one array per field (capacity 2N: a compressed octree of N
/// particles has at most N leaves and fewer internal nodes).
struct Topology {
  std::uint32_t* begin;
  std::uint32_t* count;
  std::int32_t* first_child;
  std::int32_t* num_children;
};

/// First index in [lo, hi) whose octal digit at `shift` is not d (the digits there are sorted and
/// >= d): the host's std::partition_point with the predicate digit == d.
__device__ std::uint32_t digit_end(const std::uint64_t* keys, std::uint32_t lo, std::uint32_t hi, int shift,
                                   std::uint64_t d) {
  while (lo < hi) {
    const std::uint32_t mid = lo + (hi - lo) / 2;
    if (((keys[mid] >> shift) & 7) == d)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo;
}

/// The octal digit at which node's keys split (-1: a leaf), as tree.cpp's build_nodes.
__device__ int split_shift(const std::uint64_t* keys, std::uint32_t b, std::uint32_t count, int leaf_size) {
  if (count <= static_cast<std::uint32_t>(leaf_size)) return -1;
  const std::uint64_t diff = keys[b] ^ keys[b + count - 1];
  if (diff == 0) return -1;  // identical keys (coincident particles): stays a leaf
  const int high_bit = 63 - __clzll(static_cast<long long>(diff));
  return (high_bit / 3) * 3;
}

/// Pass 1 of a level: the number of (non-empty) children of each node.
__global__ void count_children(const std::uint64_t* keys, Topology t, int first, int num, int leaf_size,
                               int* child_count) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= num) return;
  const int node = first + s;
  const std::uint32_t b = t.begin[node], e = b + t.count[node];
  const int shift = split_shift(keys, b, t.count[node], leaf_size);
  int children = 0;
  if (shift >= 0) {
    std::uint32_t start = b;
    for (std::uint64_t digit = 0; digit < 8 && start < e; ++digit) {
      const std::uint32_t stop = digit_end(keys, start, e, shift, digit);
      if (stop > start) ++children;
      start = stop;
    }
  }
  child_count[s] = children;
}

/// Pass 2 of a level: each node's children written at next_first + its prefix sum.
__global__ void write_children(const std::uint64_t* keys, Topology t, int first, int num, int leaf_size,
                               const int* child_count, const int* child_offset, int next_first) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= num) return;
  const int node = first + s;
  if (child_count[s] == 0) {
    t.first_child[node] = -1;
    t.num_children[node] = 0;
    return;
  }
  const std::uint32_t b = t.begin[node], e = b + t.count[node];
  const int shift = split_shift(keys, b, t.count[node], leaf_size);
  int c = next_first + child_offset[s];
  t.first_child[node] = c;
  t.num_children[node] = child_count[s];
  std::uint32_t start = b;
  for (std::uint64_t digit = 0; digit < 8 && start < e; ++digit) {
    const std::uint32_t stop = digit_end(keys, start, e, shift, digit);
    if (stop > start) {
      t.begin[c] = start;
      t.count[c] = stop - start;
      ++c;
    }
    start = stop;
  }
}

/// tree.cpp's set_centre_and_size: centre of mass, size, delta; returns the squared distance from
/// the centre to the box's farthest corner.
__device__ double set_centre_and_size(BuiltNode& nd, double m, double sx, double sy, double sz) {
  nd.mass = m;
  if (m > 0) {
    nd.cx = sx / m, nd.cy = sy / m, nd.cz = sz / m;
  } else {
    nd.cx = 0.5 * (nd.lo[0] + nd.hi[0]);
    nd.cy = 0.5 * (nd.lo[1] + nd.hi[1]);
    nd.cz = 0.5 * (nd.lo[2] + nd.hi[2]);
  }
  double corner2 = 0;
  {
    const double dx = fmax(nd.cx - nd.lo[0], nd.hi[0] - nd.cx);
    const double dy = fmax(nd.cy - nd.lo[1], nd.hi[1] - nd.cy);
    const double dz = fmax(nd.cz - nd.lo[2], nd.hi[2] - nd.cz);
    corner2 = dx * dx + dy * dy + dz * dz;
  }
  nd.size = fmax(fmax(nd.hi[0] - nd.lo[0], nd.hi[1] - nd.lo[1]), nd.hi[2] - nd.lo[2]);
  {
    const double dx = nd.cx - 0.5 * (nd.lo[0] + nd.hi[0]);
    const double dy = nd.cy - 0.5 * (nd.lo[1] + nd.hi[1]);
    const double dz = nd.cz - 0.5 * (nd.lo[2] + nd.hi[2]);
    nd.delta = sqrt(dx * dx + dy * dy + dz * dz);
  }
  return corner2;
}

/// tree.cpp's leaf_moments.
__device__ void leaf_moments(const Particle* p, BuiltNode& nd) {
  double m = 0, sx = 0, sy = 0, sz = 0;
  const std::uint32_t b = nd.begin, e = nd.begin + nd.count;
  nd.lo[0] = p[b].x, nd.lo[1] = p[b].y, nd.lo[2] = p[b].z;
  nd.hi[0] = nd.lo[0], nd.hi[1] = nd.lo[1], nd.hi[2] = nd.lo[2];
  for (std::uint32_t k = b; k < e; ++k) {
    const Particle s = p[k];
    m += s.m;
    sx += s.m * s.x;
    sy += s.m * s.y;
    sz += s.m * s.z;
    nd.lo[0] = fmin(nd.lo[0], s.x), nd.lo[1] = fmin(nd.lo[1], s.y), nd.lo[2] = fmin(nd.lo[2], s.z);
    nd.hi[0] = fmax(nd.hi[0], s.x), nd.hi[1] = fmax(nd.hi[1], s.y), nd.hi[2] = fmax(nd.hi[2], s.z);
  }
  const double corner2 = set_centre_and_size(nd, m, sx, sy, sz);
  double* q = nd.q;
  for (int k = 0; k < 6; ++k) q[k] = 0.0;
  double b2 = 0;
  for (std::uint32_t k = b; k < e; ++k) {
    const Particle s = p[k];
    const double dx = s.x - nd.cx, dy = s.y - nd.cy, dz = s.z - nd.cz;
    q[0] += s.m * dx * dx;
    q[1] += s.m * dx * dy;
    q[2] += s.m * dx * dz;
    q[3] += s.m * dy * dy;
    q[4] += s.m * dy * dz;
    q[5] += s.m * dz * dz;
    b2 = fmax(b2, dx * dx + dy * dy + dz * dz);
  }
  nd.bmax = sqrt(fmin(b2, corner2)) * kBmaxSafety;
}

/// tree.cpp's parent_moments (children combined by the parallel-axis theorem).
__device__ void parent_moments(const BuiltNode* nodes, int first_child, BuiltNode& nd) {
  double m = 0, sx = 0, sy = 0, sz = 0;
  const BuiltNode& c0 = nodes[first_child];
  for (int d = 0; d < 3; ++d) nd.lo[d] = c0.lo[d], nd.hi[d] = c0.hi[d];
  for (int c = 0; c < nd.num_children; ++c) {
    const BuiltNode& ch = nodes[first_child + c];
    m += ch.mass;
    sx += ch.mass * ch.cx;
    sy += ch.mass * ch.cy;
    sz += ch.mass * ch.cz;
    for (int d = 0; d < 3; ++d) {
      nd.lo[d] = fmin(nd.lo[d], ch.lo[d]);
      nd.hi[d] = fmax(nd.hi[d], ch.hi[d]);
    }
  }
  const double corner2 = set_centre_and_size(nd, m, sx, sy, sz);
  double* q = nd.q;
  for (int k = 0; k < 6; ++k) q[k] = 0.0;
  double bound = 0;
  for (int c = 0; c < nd.num_children; ++c) {
    const BuiltNode& ch = nodes[first_child + c];
    const double* qc = ch.q;
    const double dx = ch.cx - nd.cx, dy = ch.cy - nd.cy, dz = ch.cz - nd.cz;
    q[0] += qc[0] + ch.mass * dx * dx;
    q[1] += qc[1] + ch.mass * dx * dy;
    q[2] += qc[2] + ch.mass * dx * dz;
    q[3] += qc[3] + ch.mass * dy * dy;
    q[4] += qc[4] + ch.mass * dy * dz;
    q[5] += qc[5] + ch.mass * dz * dz;
    bound = fmax(bound, sqrt(dx * dx + dy * dy + dz * dz) + ch.bmax);
  }
  nd.bmax = fmin(bound, sqrt(corner2)) * kBmaxSafety;
}

/// Moments of the nodes [first, first + num) of one level, their children done.
__global__ void level_moments(const Particle* particles, Topology t, int first, int num, BuiltNode* nodes) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= num) return;
  const int node = first + s;
  BuiltNode nd{};
  nd.begin = t.begin[node];
  nd.count = t.count[node];
  nd.num_children = t.num_children[node];
  if (t.first_child[node] < 0)
    leaf_moments(particles, nd);
  else
    parent_moments(nodes, t.first_child[node], nd);
  nodes[node] = nd;
}

/// Number of nodes in each node's subtree, for one level, the deeper levels done.
__global__ void subtree_sizes(Topology t, int first, int num, int* size) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= num) return;
  const int node = first + s;
  int nodes = 1;
  for (int c = 0; c < t.num_children[node]; ++c) nodes += size[t.first_child[node] + c];
  size[node] = nodes;
}

/// Depth-first preorder positions of the children of one level's nodes (their own are set).
__global__ void preorder_children(Topology t, int first, int num, const int* size, int* preorder) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= num) return;
  const int node = first + s;
  int next = preorder[node] + 1;
  for (int c = 0; c < t.num_children[node]; ++c) {
    preorder[t.first_child[node] + c] = next;
    next += size[t.first_child[node] + c];
  }
}

__global__ void children_in_preorder(Topology t, int total, const int* preorder, int* num_children) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < total) num_children[preorder[i]] = t.num_children[i];
}

/// The host's node numbers (tree.cpp's build_nodes): it splits the nodes in depth-first preorder and
/// appends each one's children as a block, so a node's first child is numbered 1 + the number of
/// children of the nodes before it in preorder (children_before, an exclusive prefix sum).
__global__ void host_numbers(Topology t, int total, const int* preorder, const int* children_before, int* number) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= total) return;
  if (i == 0) number[0] = 0;
  const int base = 1 + children_before[preorder[i]];
  for (int c = 0; c < t.num_children[i]; ++c) number[t.first_child[i] + c] = base + c;
}

/// Each node at its host number: its full record, and the walk's with the opening radius for
/// 1 / theta (Tree::opening_radius2).
__global__ void renumber_nodes(const BuiltNode* nodes, Topology t, int total, const int* number, double inv_theta,
                               BuiltNode* built_out, WalkNode* walk_out) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= total) return;
  const BuiltNode& nd = nodes[i];
  const double r_open = fmax(nd.bmax, nd.size * inv_theta + nd.delta);
  WalkNode w{};
  w.cx = nd.cx, w.cy = nd.cy, w.cz = nd.cz;
  w.mass = nd.mass;
  w.r_open2 = r_open * r_open;
  for (int k = 0; k < 6; ++k) w.q[k] = nd.q[k];
  w.begin = nd.begin, w.count = nd.count;
  w.first_child = t.first_child[i] >= 0 ? number[t.first_child[i]] : -1;
  w.num_children = t.num_children[i];
  walk_out[number[i]] = w;
  built_out[number[i]] = nd;
}

/// Adds node nd to group g (tree.cpp's collect_groups: the first node sets the range and the box).
__device__ void add_to_group(const BuiltNode& nd, BuiltGroup& g) {
  if (g.count == 0) {
    g.begin = nd.begin;
    for (int d = 0; d < 3; ++d) g.lo[d] = nd.lo[d], g.hi[d] = nd.hi[d];
  } else {
    for (int d = 0; d < 3; ++d) g.lo[d] = fmin(g.lo[d], nd.lo[d]), g.hi[d] = fmax(g.hi[d], nd.hi[d]);
  }
  g.count += nd.count;
}

/// The groups that node i makes (tree.cpp's collect_groups, which visits the root and every node
/// of more than gmax particles with children): the root alone when it is small or a leaf; for a
/// large node with children, its large leaf children one each and runs of consecutive small
/// children packed up to gmax particles. Counts them (out == nullptr) or writes them.
__device__ int node_groups(const BuiltNode* nodes, Topology t, int i, std::uint32_t gmax, BuiltGroup* out) {
  const BuiltNode& nd = nodes[i];
  const bool leaf = t.first_child[i] < 0;
  int made = 0;
  auto emit = [&](BuiltGroup& g) {
    if (out) out[made] = g;
    ++made;
    g = BuiltGroup{};
  };
  if (i == 0 && (leaf || nd.count <= gmax)) {
    BuiltGroup g{};
    add_to_group(nd, g);
    emit(g);
    return made;
  }
  if (leaf || nd.count <= gmax) return 0;
  BuiltGroup run{};
  for (int c = 0; c < t.num_children[i]; ++c) {
    const int ci = t.first_child[i] + c;
    const BuiltNode& ch = nodes[ci];
    if (ch.count > gmax) {
      if (run.count > 0) emit(run);
      if (t.first_child[ci] < 0) {
        BuiltGroup g{};
        add_to_group(ch, g);
        emit(g);
      }
      continue;
    }
    if (run.count > 0 && run.count + ch.count > gmax) emit(run);
    add_to_group(ch, run);
  }
  if (run.count > 0) emit(run);
  return made;
}

__global__ void count_groups(const BuiltNode* nodes, Topology t, int num, std::uint32_t gmax, int* group_count) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < num) group_count[i] = node_groups(nodes, t, i, gmax, nullptr);
}

__global__ void write_groups(const BuiltNode* nodes, Topology t, int num, std::uint32_t gmax, const int* group_offset,
                             BuiltGroup* groups) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < num) node_groups(nodes, t, i, gmax, groups + group_offset[i]);
}

/// Exclusive prefix sum of n ints on the device (CUB); returns the total (synchronises).
int exclusive_sum(const int* in, int* out, int n, DeviceBuffer<unsigned char>& scratch) {
  if (n == 0) return 0;
  std::size_t bytes = 0;
  check(cub::DeviceScan::ExclusiveSum(nullptr, bytes, in, out, n), "prefix sum");
  if (bytes > scratch.size()) scratch.allocate(bytes);
  check(cub::DeviceScan::ExclusiveSum(scratch.get(), bytes, in, out, n), "prefix sum");
  int last_in = 0, last_out = 0;
  check(cudaMemcpy(&last_in, in + n - 1, sizeof(int), cudaMemcpyDeviceToHost), "copy from the GPU");
  check(cudaMemcpy(&last_out, out + n - 1, sizeof(int), cudaMemcpyDeviceToHost), "copy from the GPU");
  return last_out + last_in;
}

}  // namespace

DeviceTree build_tree(const TreeFieldInput& in, const double* positions, const double* masses) {
  const std::size_t n = in.n;
  const int ni = static_cast<int>(n);
  DeviceTree tree;
  DeviceBuffer<unsigned char> scratch;

  // 1-2. Keys, stable sort, particles in Morton order.
  {
    DeviceBuffer<std::uint64_t> keys(n);
    DeviceBuffer<std::uint32_t> index(n);
    tree.order.allocate(n);
    const double scale = in.extent > 0 ? morton::kCells / in.extent : 0.0;
    morton_keys<<<blocks_for(n), kBlock>>>(positions, ni, in.lo[0], in.lo[1], in.lo[2], scale, keys.get(), index.get());
    check(cudaGetLastError(), "Morton keys");
    DeviceBuffer<std::uint64_t> sorted_keys(n);
    std::size_t bytes = 0;
    check(cub::DeviceRadixSort::SortPairs(nullptr, bytes, keys.get(), sorted_keys.get(), index.get(), tree.order.get(),
                                          ni, 0, 63),
          "radix sort");
    scratch.allocate(bytes);
    check(cub::DeviceRadixSort::SortPairs(scratch.get(), bytes, keys.get(), sorted_keys.get(), index.get(),
                                          tree.order.get(), ni, 0, 63),
          "radix sort");
    tree.particles.allocate(n);
    gather_particles<<<blocks_for(n), kBlock>>>(positions, masses, tree.order.get(), ni, tree.particles.get());
    check(cudaGetLastError(), "gather");

    // 3. Nodes level by level: levels[L] = (first node, number of nodes).
    const std::size_t capacity = 2 * n;
    DeviceBuffer<std::uint32_t> begin(capacity), count(capacity);
    DeviceBuffer<std::int32_t> first_child(capacity), num_children(capacity);
    const Topology t{begin.get(), count.get(), first_child.get(), num_children.get()};
    const std::uint32_t root[2] = {0, static_cast<std::uint32_t>(n)};
    check(cudaMemcpy(begin.get(), &root[0], sizeof(std::uint32_t), cudaMemcpyHostToDevice), "copy to the GPU");
    check(cudaMemcpy(count.get(), &root[1], sizeof(std::uint32_t), cudaMemcpyHostToDevice), "copy to the GPU");
    DeviceBuffer<int> child_count(n), child_offset(n);
    std::vector<std::pair<int, int>> levels;
    int first = 0, num = 1, total = 1;
    while (num > 0) {
      levels.emplace_back(first, num);
      count_children<<<blocks_for(static_cast<std::size_t>(num)), kBlock>>>(sorted_keys.get(), t, first, num,
                                                                            in.leaf_size, child_count.get());
      check(cudaGetLastError(), "count children");
      const int next = exclusive_sum(child_count.get(), child_offset.get(), num, scratch);
      if (static_cast<std::size_t>(total) + static_cast<std::size_t>(next) > capacity)
        throw std::runtime_error("CUDA tree: more nodes than 2N (internal error)");
      write_children<<<blocks_for(static_cast<std::size_t>(num)), kBlock>>>(
          sorted_keys.get(), t, first, num, in.leaf_size, child_count.get(), child_offset.get(), total);
      check(cudaGetLastError(), "write children");
      first = total, num = next, total += next;
    }

    // 4. Moments, deepest level first.
    const auto nodes_total = static_cast<std::size_t>(total);
    const int node_blocks = blocks_for(nodes_total);
    DeviceBuffer<BuiltNode> level_order(nodes_total);
    for (auto it = levels.rbegin(); it != levels.rend(); ++it) {
      level_moments<<<blocks_for(static_cast<std::size_t>(it->second)), kBlock>>>(tree.particles.get(), t, it->first,
                                                                                  it->second, level_order.get());
      check(cudaGetLastError(), "moments");
    }

    // 5. Groups (they name particle ranges, not nodes: the numbering does not matter).
    DeviceBuffer<int> group_count(nodes_total), group_offset(nodes_total);
    const auto gmax = static_cast<std::uint32_t>(in.group_size);
    count_groups<<<node_blocks, kBlock>>>(level_order.get(), t, total, gmax, group_count.get());
    check(cudaGetLastError(), "count groups");
    const int num_groups = exclusive_sum(group_count.get(), group_offset.get(), total, scratch);
    tree.groups.allocate(static_cast<std::size_t>(num_groups));
    write_groups<<<node_blocks, kBlock>>>(level_order.get(), t, total, gmax, group_offset.get(), tree.groups.get());
    check(cudaGetLastError(), "write groups");

    // 6. The host's numbering (depth first): subtrees bottom-up, preorder top-down, then each
    //    node's children placed after the children of the nodes before it in preorder. The node
    //    array is then Tree::nodes() itself (compared node by node in the tests), and a subtree's
    //    nodes are close in memory.
    DeviceBuffer<int> size(nodes_total), preorder(nodes_total), children(nodes_total), before(nodes_total),
        number(nodes_total);
    for (auto it = levels.rbegin(); it != levels.rend(); ++it) {
      subtree_sizes<<<blocks_for(static_cast<std::size_t>(it->second)), kBlock>>>(t, it->first, it->second, size.get());
      check(cudaGetLastError(), "subtree sizes");
    }
    check(cudaMemset(preorder.get(), 0, sizeof(int)), "cudaMemset");
    for (const auto& [level_first, level_num] : levels) {
      preorder_children<<<blocks_for(static_cast<std::size_t>(level_num)), kBlock>>>(t, level_first, level_num,
                                                                                     size.get(), preorder.get());
      check(cudaGetLastError(), "preorder");
    }
    children_in_preorder<<<node_blocks, kBlock>>>(t, total, preorder.get(), children.get());
    check(cudaGetLastError(), "children in preorder");
    exclusive_sum(children.get(), before.get(), total, scratch);
    host_numbers<<<node_blocks, kBlock>>>(t, total, preorder.get(), before.get(), number.get());
    check(cudaGetLastError(), "node numbers");
    tree.built_nodes.allocate(nodes_total);
    tree.nodes.allocate(nodes_total);
    renumber_nodes<<<node_blocks, kBlock>>>(level_order.get(), t, total, number.get(), 1.0 / in.theta,
                                            tree.built_nodes.get(), tree.nodes.get());
    check(cudaGetLastError(), "renumber nodes");
    check(cudaDeviceSynchronize(), "tree build");
  }
  return tree;
}

}  // namespace rubble::gravity::cuda::detail
