// GPU tree walk: the CPU tree's group walk (gravity/tree.cpp) on a GPU, over the tree that
// tree_build.cu built there, one thread block per group of targets. The block walks the tree together, a chunk of up to
// kThreads nodes at a time: each thread applies the opening criterion to one node, and block-wide prefix sums place the
// accepted nodes (multipoles), the opened leaves (particle ranges) and the children of the opened nodes (onto the
// block's stack) without atomics. When the lists in shared memory are full they are evaluated, each thread summing them
// onto its own targets, and emptied. This is the shared interaction list of Barnes (1990) as GPU tree codes use it
// (Bédorf, Gaburov & Portegies Zwart 2012, "A sparse octree gravitational N-body code that runs entirely on the GPU",
// J. Comput. Phys. 231, 2825: a warp-wide walk of a group with the lists built by prefix sums).
//
// Determinism: a group's walk, its lists and each target's sum depend only on the tree, not on
// which block runs the group or how many blocks there are, so results are the same run to run and
// on any GPU (with the same CUDA version).

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "gravity/cuda/device_tree.cuh"
#include "gravity/cuda/interactions.cuh"

namespace rubble::gravity::cuda::detail {
namespace {

constexpr int kThreads = 64;  // the default group_size: one target per thread in most groups
constexpr int kWarps = kThreads / 32;
constexpr int kCellCapacity = 1024;    // accepted nodes held before the lists are evaluated
constexpr int kRangeCapacity = 512;    // particle ranges (opened leaves) held before that
constexpr int kStackCapacity = 16384;  // nodes still to test, per block (global memory)
constexpr unsigned kFullMask = 0xffffffffu;

/// What the walk kernel reads and writes (device pointers).
struct WalkArrays {
  const Particle* particles;
  const std::uint32_t* order;  // the caller's index of each particle
  const WalkNode* nodes;
  const BuiltGroup* groups;
  int num_groups;
  bool quadrupole;
  double eps2, G;
  double* sums;   // 4 per particle: running a/(-G) and phi/(-G) between two evaluations of the lists
  double* acc;    // 3 per particle, the result, in the caller's order
  double* pot;    // 1 per particle or nullptr, the caller's order
  int* stacks;    // kStackCapacity per block
  int* overflow;  // set to 1 when a stack would overflow
};

/// Exclusive prefix sums over the block of three counts per thread, and their totals.
/// warp_totals: shared scratch of kWarps x 3.
__device__ void block_exclusive_scan3(const int value[3], int offset[3], int total[3], int (*warp_totals)[3]) {
  const int lane = static_cast<int>(threadIdx.x) & 31, warp = static_cast<int>(threadIdx.x) >> 5;
  int inclusive[3];
  for (int c = 0; c < 3; ++c) {
    int x = value[c];
    for (int o = 1; o < 32; o <<= 1) {
      const int y = __shfl_up_sync(kFullMask, x, o);
      if (lane >= o) x += y;
    }
    inclusive[c] = x;
  }
  if (lane == 31)
    for (int c = 0; c < 3; ++c) warp_totals[warp][c] = inclusive[c];
  __syncthreads();
  for (int c = 0; c < 3; ++c) {
    int before = 0, sum = 0;
    for (int w = 0; w < kWarps; ++w) {
      if (w < warp) before += warp_totals[w][c];
      sum += warp_totals[w][c];
    }
    offset[c] = before + inclusive[c] - value[c];
    total[c] = sum;
  }
  __syncthreads();  // warp_totals is reused by the next call
}

/// Squared distance from a point to the group's box (0 inside), as the CPU walk computes it.
__device__ double dist2_point_box(double px, double py, double pz, const BuiltGroup& g) {
  const double dx = fmax(fmax(g.lo[0] - px, 0.0), px - g.hi[0]);
  const double dy = fmax(fmax(g.lo[1] - py, 0.0), py - g.hi[1]);
  const double dz = fmax(fmax(g.lo[2] - pz, 0.0), pz - g.hi[2]);
  return dx * dx + dy * dy + dz * dz;
}

/// Adds the field of the lists (cells and particle ranges) on each target of the group, in the
/// order of the lists. first: the targets' running sums start at zero; last: the result is
/// written (times -G, the softened self term removed) instead of the running sums.
__device__ void evaluate_lists(const WalkArrays& t, const BuiltGroup& g, const int* cells, int num_cells,
                               const uint2* ranges, int num_ranges, bool first, bool last) {
  for (unsigned k = threadIdx.x; k < g.count; k += kThreads) {
    const unsigned i = g.begin + k;
    const Particle me = t.particles[i];
    double ax = 0, ay = 0, az = 0, phi = 0;
    if (!first) ax = t.sums[4 * i], ay = t.sums[4 * i + 1], az = t.sums[4 * i + 2], phi = t.sums[4 * i + 3];
    for (int r = 0; r < num_ranges; ++r) {
      const uint2 range = ranges[r];
      for (unsigned j = range.x; j < range.x + range.y; ++j) {
        const Particle s = t.particles[j];
        add_particle(me.x, me.y, me.z, s.x, s.y, s.z, s.m, t.eps2, ax, ay, az, phi);
      }
    }
    for (int c = 0; c < num_cells; ++c) {
      const WalkNode& nd = t.nodes[cells[c]];
      const double rx = me.x - nd.cx, ry = me.y - nd.cy, rz = me.z - nd.cz;
      // Accepted nodes are well separated (distance > b_max >= 0): r2 > 0.
      const double r2 = rx * rx + ry * ry + rz * rz + t.eps2;
      const double d1 = rsqrt(r2);
      const double d2 = d1 * d1;
      const double d3 = d1 * d2;
      if (!t.quadrupole) {  // the node as a point mass at its centre of mass
        const double m_d3 = nd.mass * d3;
        ax += rx * m_d3;
        ay += ry * m_d3;
        az += rz * m_d3;
        phi += nd.mass * d1;
        continue;
      }
      // The quadrupole formulas of gravity/kernels.hpp (m2p_quadrupole).
      const double d5 = d3 * d2;
      const double d7 = d5 * d2;
      const double* q = nd.q;
      const double mrx = q[0] * rx + q[1] * ry + q[2] * rz;
      const double mry = q[1] * rx + q[3] * ry + q[4] * rz;
      const double mrz = q[2] * rx + q[4] * ry + q[5] * rz;
      const double rmr = rx * mrx + ry * mry + rz * mrz;
      const double tr = q[0] + q[3] + q[5];
      const double radial = nd.mass * d3 - 1.5 * d5 * tr + 7.5 * d7 * rmr;
      const double d5x3 = 3.0 * d5;
      ax += radial * rx - d5x3 * mrx;
      ay += radial * ry - d5x3 * mry;
      az += radial * rz - d5x3 * mrz;
      phi += nd.mass * d1 + 1.5 * d5 * rmr - 0.5 * d3 * tr;
    }
    if (!last) {
      t.sums[4 * i] = ax, t.sums[4 * i + 1] = ay, t.sums[4 * i + 2] = az, t.sums[4 * i + 3] = phi;
      continue;
    }
    // The target's own leaf is always opened, so with softening its self term m / eps is in phi.
    if (t.eps2 > 0.0) phi -= me.m * rsqrt(t.eps2);
    const std::uint32_t o = t.order[i];
    t.acc[3 * o] = -t.G * ax;
    t.acc[3 * o + 1] = -t.G * ay;
    t.acc[3 * o + 2] = -t.G * az;
    if (t.pot) t.pot[o] = -t.G * phi;
  }
}

__global__ void __launch_bounds__(kThreads) walk_groups(WalkArrays t) {
  __shared__ int cells[kCellCapacity];
  __shared__ uint2 ranges[kRangeCapacity];
  __shared__ int warp_totals[kWarps][3];
  __shared__ int num_cells, num_ranges, stack_size;
  int* stack = t.stacks + static_cast<std::size_t>(blockIdx.x) * kStackCapacity;
  const int tid = static_cast<int>(threadIdx.x);
  for (int gi = static_cast<int>(blockIdx.x); gi < t.num_groups; gi += static_cast<int>(gridDim.x)) {
    const BuiltGroup g = t.groups[gi];
    if (tid == 0) {
      stack[0] = 0;  // the root
      stack_size = 1;
      num_cells = 0;
      num_ranges = 0;
    }
    __syncthreads();
    bool first = true;  // no evaluation of the lists yet for this group
    bool overflowed = false;
    while (true) {
      const int size = stack_size, nc = num_cells, nr = num_ranges;  // same in every thread
      if (size == 0) break;
      if (nc + kThreads > kCellCapacity || nr + kThreads > kRangeCapacity) {  // no room for one more chunk
        evaluate_lists(t, g, cells, nc, ranges, nr, first, false);
        first = false;
        __syncthreads();
        if (tid == 0) num_cells = 0, num_ranges = 0;
        __syncthreads();
        continue;
      }
      // Pop a chunk from the top of the stack; each thread tests one node of it.
      const int take = min(size, kThreads), base = size - take;
      int node = -1;
      int count[3] = {0, 0, 0};  // accepted as a cell, opened or tiny (a particle range), children to push
      uint2 range = make_uint2(0, 0);
      int first_child = 0;
      if (tid < take) {
        node = stack[base + tid];
        const WalkNode& nd = t.nodes[node];
        range = make_uint2(nd.begin, nd.count);
        first_child = nd.first_child;
        if (dist2_point_box(nd.cx, nd.cy, nd.cz, g) > nd.r_open2) {
          // Quadrupole evaluations cost about two particle interactions: nodes of < 3 particles
          // are summed directly (as on the CPU). A monopole cell is a point mass.
          if (t.quadrupole && nd.count < 3)
            count[1] = 1;
          else
            count[0] = 1;
        } else if (nd.first_child < 0) {
          count[1] = 1;
        } else {
          count[2] = nd.num_children;
        }
      }
      int offset[3], total[3];
      block_exclusive_scan3(count, offset, total, warp_totals);  // also orders the stack reads before the writes
      if (base + total[2] > kStackCapacity) {                    // same decision in every thread
        overflowed = true;
        break;
      }
      if (count[0]) cells[nc + offset[0]] = node;
      if (count[1]) ranges[nr + offset[1]] = range;
      // Children pushed last-first, so that the first child is near the top of the stack.
      for (int c = 0; c < count[2]; ++c) stack[base + offset[2] + c] = first_child + count[2] - 1 - c;
      __syncthreads();
      if (tid == 0) {
        stack_size = base + total[2];
        num_cells = nc + total[0];
        num_ranges = nr + total[1];
      }
      __syncthreads();
    }
    if (overflowed) {
      if (tid == 0) atomicExch(t.overflow, 1);
    } else {
      evaluate_lists(t, g, cells, num_cells, ranges, num_ranges, first, true);
    }
    __syncthreads();  // the shared lists and counters are reset by the next group
  }
}

template <class T>
void upload(DeviceBuffer<T>& to, const T* from, std::size_t n) {
  to.allocate(n);
  if (n > 0) check(cudaMemcpy(to.get(), from, n * sizeof(T), cudaMemcpyHostToDevice), "copy to the GPU");
}

template <class T>
void download(T* to, const DeviceBuffer<T>& from) {
  if (from.size() > 0)
    check(cudaMemcpy(to, from.get(), from.size() * sizeof(T), cudaMemcpyDeviceToHost), "copy from the GPU");
}

double seconds(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

void check_size(const TreeFieldInput& in) {
  if (in.n > static_cast<std::size_t>(INT_MAX / 4))
    throw std::runtime_error("CUDA tree: too many particles for 32-bit indices");
}

/// Walks tree for every group; results into acc (3N) and pot (N or nullptr), caller's order.
void walk(const TreeFieldInput& in, const DeviceTree& tree, double* acc, double* pot) {
  const std::size_t n = in.n, num_groups = tree.groups.size();
  DeviceBuffer<double> sums(4 * n);
  // As many blocks as can be resident at once, each walking groups blockIdx.x + k * gridDim.x:
  // the stacks (64 KiB a block) exist for resident blocks only.
  int device = 0, sms = 0, per_sm = 0;
  check(cudaGetDevice(&device), "cudaGetDevice");
  check(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device), "multiprocessor count");
  check(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, walk_groups, kThreads, 0), "occupancy");
  const std::size_t resident = static_cast<std::size_t>(std::max(1, sms * std::max(1, per_sm)));
  const int blocks = static_cast<int>(std::min(num_groups, resident));
  DeviceBuffer<int> stacks(static_cast<std::size_t>(blocks) * kStackCapacity), overflow(1);
  check(cudaMemset(overflow.get(), 0, sizeof(int)), "cudaMemset");
  const WalkArrays t{tree.particles.get(),
                     tree.order.get(),
                     tree.nodes.get(),
                     tree.groups.get(),
                     static_cast<int>(num_groups),
                     in.quadrupole,
                     in.eps2,
                     in.G,
                     sums.get(),
                     acc,
                     pot,
                     stacks.get(),
                     overflow.get()};
  walk_groups<<<blocks, kThreads>>>(t);
  check(cudaGetLastError(), "walk launch");
  check(cudaDeviceSynchronize(), "walk");
  int overflowed = 0;
  check(cudaMemcpy(&overflowed, overflow.get(), sizeof(int), cudaMemcpyDeviceToHost), "copy from the GPU");
  if (overflowed)
    throw std::runtime_error("CUDA tree: a group's node stack exceeded " + std::to_string(kStackCapacity) +
                             " entries (tree too deep or too wide for the GPU walk)");
}

}  // namespace

void tree_field(const TreeFieldInput& in, double* acc, double* pot, TreeFieldTimings* timings) {
  using Clock = std::chrono::steady_clock;
  const std::size_t n = in.n;
  if (n == 0) return;
  check_size(in);
  const auto t0 = Clock::now();
  DeviceBuffer<double> positions, masses;
  upload(positions, in.positions, 3 * n);
  upload(masses, in.masses, n);
  DeviceBuffer<double> dacc(3 * n), dpot(pot ? n : 0);
  const auto t1 = Clock::now();
  const DeviceTree tree = build_tree(in, positions.get(), masses.get());
  const auto t2 = Clock::now();
  walk(in, tree, dacc.get(), dpot.get());
  const auto t3 = Clock::now();
  download(acc, dacc);
  if (pot) download(pot, dpot);
  const auto t4 = Clock::now();
  if (timings) *timings = {seconds(t1, t2), seconds(t2, t3), seconds(t0, t1) + seconds(t3, t4)};
}

BuiltTree build_tree_for_test(const TreeFieldInput& in) {
  BuiltTree out;
  if (in.n == 0) return out;
  check_size(in);
  DeviceBuffer<double> positions, masses;
  upload(positions, in.positions, 3 * in.n);
  upload(masses, in.masses, in.n);
  const DeviceTree tree = build_tree(in, positions.get(), masses.get());
  out.nodes.resize(tree.built_nodes.size());
  out.order.resize(tree.order.size());
  out.groups.resize(tree.groups.size());
  download(out.nodes.data(), tree.built_nodes);
  download(out.order.data(), tree.order);
  download(out.groups.data(), tree.groups);
  return out;
}

}  // namespace rubble::gravity::cuda::detail
