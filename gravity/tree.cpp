#include "gravity/tree.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <type_traits>

#include "gravity/kernels.hpp"
#include "gravity/morton.hpp"

namespace rubble::gravity {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// b_max is rounded up by a few ulps so that a node containing a target can never pass the
// (strict) acceptance test through rounding, even with theta >= 1.
constexpr double kBmaxSafety = 1.0 + 1e-12;
// Below these sizes the OpenMP loops run on the calling thread only (same results: the threads
// never change the order of any sum). A parallel region costs a team wake-up and a barrier, ~10 us
// on an idle machine but milliseconds of spinning CPU on a loaded one, where the other thread is
// not scheduled at once: at N = 10^4 (walk ~14 ms of CPU) two threads used 2-3x the CPU of one and
// were slower in wall time too on the shared 2-core machine (bench/RESULTS.md, "Gravity"). The key
// loop is ~10 ns a particle: threads only pay off for very large N.
constexpr std::size_t kParallelWalkMin = std::size_t{1} << 14;  // 16 384 targets
constexpr std::size_t kParallelKeysMin = std::size_t{1} << 18;  // 262 144 particles

/// Stable LSD radix sort of (key, index) pairs on 8-bit digits. Stable + keys computed from the
/// positions only => the order does not depend on anything but the input (determinism). From
/// kParallelKeysMin keys each pass runs on all threads: each counts the digits of its own
/// contiguous slice, and scatters the slice to the offsets of its digits, after those of every
/// smaller digit and of the same digit in the slices before its own. That is exactly where the
/// serial stable pass puts each key, so the result is the same for any thread count. k2 and i2
/// are the passes' second buffers (resized here).
void radix_sort(std::vector<std::uint64_t>& keys, std::vector<std::uint32_t>& idx, std::vector<std::uint64_t>& k2,
                std::vector<std::uint32_t>& i2) {
  const std::size_t n = keys.size();
  k2.resize(n);
  i2.resize(n);
  const bool parallel = n >= kParallelKeysMin;
  const int slices = parallel ? omp_get_max_threads() : 1;
  // counts[s][d]: keys of slice s with digit d; then the first position of those keys.
  std::vector<std::array<std::size_t, 256>> counts(static_cast<std::size_t>(slices));
  const auto slice_begin = [&](int s) { return n * static_cast<std::size_t>(s) / static_cast<std::size_t>(slices); };
  for (int shift = 0; shift < 64; shift += 8) {
    const auto count_slice = [&](int s) {
      auto& c = counts[static_cast<std::size_t>(s)];
      c.fill(0);
      const std::size_t b = slice_begin(s), e = slice_begin(s + 1);
      for (std::size_t i = b; i < e; ++i) ++c[(keys[i] >> shift) & 0xff];
    };
    const auto scatter_slice = [&](int s) {
      auto& next = counts[static_cast<std::size_t>(s)];
      const std::size_t b = slice_begin(s), e = slice_begin(s + 1);
      for (std::size_t i = b; i < e; ++i) {
        const std::size_t dst = next[(keys[i] >> shift) & 0xff]++;
        k2[dst] = keys[i];
        i2[dst] = idx[i];
      }
    };
    // Small inputs stay off OpenMP altogether: a parallel region, even of one thread, costs
    // about as much as sorting 125 keys (16 of them a sort).
    if (parallel) {
#pragma omp parallel for schedule(static, 1) num_threads(slices)
      for (int s = 0; s < slices; ++s) count_slice(s);
    } else {
      count_slice(0);
    }
    // A digit shared by all keys leaves the order unchanged: skip the pass.
    bool constant = false;
    std::size_t start = 0;
    for (std::size_t d = 0; d < 256; ++d) {
      std::size_t digit_total = 0;
      for (const auto& c : counts) digit_total += c[d];
      if (digit_total == n) constant = true;
      for (auto& c : counts) {
        const std::size_t count = c[d];
        c[d] = start;
        start += count;
      }
    }
    if (constant) continue;
    if (parallel) {
#pragma omp parallel for schedule(static, 1) num_threads(slices)
      for (int s = 0; s < slices; ++s) scatter_slice(s);
    } else {
      scatter_slice(0);
    }
    keys.swap(k2);
    idx.swap(i2);
  }
}

/// Squared distance from point p to the box [lo, hi] (0 inside).
inline double dist2_point_box(double px, double py, double pz, const std::array<double, 3>& lo,
                              const std::array<double, 3>& hi) {
  const double dx = std::max({lo[0] - px, 0.0, px - hi[0]});
  const double dy = std::max({lo[1] - py, 0.0, py - hi[1]});
  const double dz = std::max({lo[2] - pz, 0.0, pz - hi[2]});
  return dx * dx + dy * dy + dz * dz;
}

/// The particles' Morton keys in a 21-bit grid over their bounding cube, sorted, into `keys`;
/// `order` receives the permutation that sorts them (order[k] = index of the k-th particle along
/// the curve). sort_keys and sort_order: the radix sort's buffers.
void sorted_morton_keys(std::span<const double> positions, std::vector<std::uint32_t>& order,
                        std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& sort_keys,
                        std::vector<std::uint32_t>& sort_order) {
  const std::size_t n = order.size();
  std::array<double, 3> lo{};
  double extent = 0;
  Tree::bounding_cube(positions, lo, extent);
  const double scale = extent > 0 ? morton::kCells / extent : 0.0;
  keys.resize(n);
  const auto sn = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) if (n >= kParallelKeysMin)
  for (std::ptrdiff_t s = 0; s < sn; ++s) {
    const auto i = static_cast<std::size_t>(s);
    keys[i] = morton::key(&positions[3 * i], lo.data(), scale);
    order[i] = static_cast<std::uint32_t>(i);
  }
  radix_sort(keys, order, sort_keys, sort_order);
}

/// Sets a node's centre of mass from its mass m and first moments (sx, sy, sz) (the box centre
/// when m = 0: the moments are zero then), its size (longest side of the box) and delta (centre
/// of mass to box centre). Returns the squared distance from the centre of mass to the box's
/// farthest corner: a bound for b_max that is always valid.
double set_centre_and_size(Tree::Node& nd, double m, double sx, double sy, double sz) {
  nd.mass = m;
  if (m > 0) {
    nd.cx = sx / m, nd.cy = sy / m, nd.cz = sz / m;
  } else {  // massless particles only: any centre works, the moments are zero
    nd.cx = 0.5 * (nd.lo[0] + nd.hi[0]);
    nd.cy = 0.5 * (nd.lo[1] + nd.hi[1]);
    nd.cz = 0.5 * (nd.lo[2] + nd.hi[2]);
  }
  double corner2 = 0;
  {
    const double dx = std::max(nd.cx - nd.lo[0], nd.hi[0] - nd.cx);
    const double dy = std::max(nd.cy - nd.lo[1], nd.hi[1] - nd.cy);
    const double dz = std::max(nd.cz - nd.lo[2], nd.hi[2] - nd.cz);
    corner2 = dx * dx + dy * dy + dz * dz;
  }
  nd.size = std::max({nd.hi[0] - nd.lo[0], nd.hi[1] - nd.lo[1], nd.hi[2] - nd.lo[2]});
  {
    const double dx = nd.cx - 0.5 * (nd.lo[0] + nd.hi[0]);
    const double dy = nd.cy - 0.5 * (nd.lo[1] + nd.hi[1]);
    const double dz = nd.cz - 0.5 * (nd.lo[2] + nd.hi[2]);
    nd.delta = std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  return corner2;
}

}  // namespace

/// Per-thread scratch for one group: the interaction lists, gathered as structure of arrays so
/// that the kernels run unit-stride over sources.
template <typename Real>
struct Tree::InteractionLists {
  std::vector<Real> px, py, pz, pm;                          // P2P sources (and monopole cells)
  std::vector<Real> cx, cy, cz, cm, xx, xy, xz, yy, yz, zz;  // quadrupole cells
  void clear() {
    for (auto* v : {&px, &py, &pz, &pm, &cx, &cy, &cz, &cm, &xx, &xy, &xz, &yy, &yz, &zz}) v->clear();
  }
};

/// Lists hold Real((x - origin) * inv_length) for coordinates, Real(m * inv_mass) for masses and
/// Real(M * inv_moment) for second moments. The double kernels use the identity (origin 0, scales
/// 1: the values exactly). The single-precision ones use offsets from the group's centre in units
/// of the root's size L and masses in units of the total mass M, so that no value leaves float's
/// range and the offsets keep float's relative precision.
struct Tree::ListUnits {
  double ox = 0, oy = 0, oz = 0;
  double inv_length = 1, inv_mass = 1, inv_moment = 1;
};

void Tree::bounding_cube(std::span<const double> positions, std::array<double, 3>& lo, double& extent) {
  double lx = positions[0], ly = positions[1], lz = positions[2], hx = lx, hy = ly, hz = lz;
  const auto n = static_cast<std::ptrdiff_t>(positions.size() / 3);
  const auto widen = [&](std::ptrdiff_t si, double& l0, double& l1, double& l2, double& h0, double& h1, double& h2) {
    const auto i = static_cast<std::size_t>(si);
    l0 = std::min(l0, positions[3 * i]), h0 = std::max(h0, positions[3 * i]);
    l1 = std::min(l1, positions[3 * i + 1]), h1 = std::max(h1, positions[3 * i + 1]);
    l2 = std::min(l2, positions[3 * i + 2]), h2 = std::max(h2, positions[3 * i + 2]);
  };
  if (n >= static_cast<std::ptrdiff_t>(kParallelKeysMin)) {
#pragma omp parallel for reduction(min : lx, ly, lz) reduction(max : hx, hy, hz)
    for (std::ptrdiff_t si = 0; si < n; ++si) widen(si, lx, ly, lz, hx, hy, hz);
  } else {  // no OpenMP region for small inputs: it costs what the loop does at N ~ 100
    for (std::ptrdiff_t si = 0; si < n; ++si) widen(si, lx, ly, lz, hx, hy, hz);
  }
  lo = {lx, ly, lz};
  extent = std::max({hx - lx, hy - ly, hz - lz});
}

Tree::Tree(int leaf_size, int group_size) : leaf_size_(leaf_size), group_size_(group_size) {
  if (leaf_size < 1) throw GravityError("Tree: leaf_size must be >= 1");
  if (group_size < 1) throw GravityError("Tree: group_size must be >= 1");
}

void Tree::load_particles(std::span<const double> positions, std::span<const double> masses) {
  const std::size_t n = masses.size();
  x_.resize(n);
  y_.resize(n);
  z_.resize(n);
  m_.resize(n);
  const auto sn = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) if (n >= kParallelKeysMin)
  for (std::ptrdiff_t sk = 0; sk < sn; ++sk) {
    const auto k = static_cast<std::size_t>(sk);
    const std::size_t i = order_[k];
    x_[k] = positions[3 * i];
    y_[k] = positions[3 * i + 1];
    z_[k] = positions[3 * i + 2];
    m_[k] = masses[i];
  }
}

double Tree::build(std::span<const double> positions, std::span<const double> masses) {
  const auto t0 = Clock::now();
  validate_particles(GravityOptions{}, positions, masses);
  const std::size_t n = masses.size();
  if (n > std::numeric_limits<std::uint32_t>::max() / 2) throw GravityError("Tree: too many particles (limit 2^31)");
  nodes_.clear();
  second_moments_.clear();
  groups_.clear();
  order_.resize(n);
  if (n == 0) {
    x_.clear(), y_.clear(), z_.clear(), m_.clear();
    return seconds_since(t0);
  }
  sorted_morton_keys(positions, order_, keys_, sort_keys_, sort_order_);
  load_particles(positions, masses);
  build_nodes(keys_);
  second_moments_.resize(nodes_.size());
  compute_moments();
  collect_groups();
  return seconds_since(t0);
}

void Tree::build_nodes(const std::vector<std::uint64_t>& keys) {
  // Nodes: recursive split of sorted key ranges by their first differing octal digit. Ranges whose
  // keys share the next digits are not split into single-child chains (compressed octree).
  nodes_.emplace_back();
  nodes_[0].begin = 0;
  nodes_[0].count = static_cast<std::uint32_t>(keys.size());
  std::vector<std::uint32_t> todo{0};
  while (!todo.empty()) {
    const std::uint32_t ni = todo.back();
    todo.pop_back();
    const std::uint32_t b = nodes_[ni].begin, e = b + nodes_[ni].count;
    if (nodes_[ni].count <= static_cast<std::uint32_t>(leaf_size_)) continue;
    const std::uint64_t diff = keys[b] ^ keys[e - 1];
    if (diff == 0) continue;  // identical keys (coincident particles): stays a leaf
    const int high_bit = 63 - std::countl_zero(diff);
    const int shift = (high_bit / 3) * 3;  // the octal digit holding the first differing bit
    const auto first_child = static_cast<std::int32_t>(nodes_.size());
    std::uint32_t start = b;
    for (std::uint64_t digit = 0; digit < 8 && start < e; ++digit) {
      const auto stop = static_cast<std::uint32_t>(
          std::partition_point(keys.begin() + start, keys.begin() + e,
                               [&](std::uint64_t k) { return ((k >> shift) & 7) == digit; }) -
          keys.begin());
      if (stop > start) {
        Node child;
        child.begin = start;
        child.count = stop - start;
        nodes_.push_back(child);
      }
      start = stop;
    }
    nodes_[ni].first_child = first_child;
    nodes_[ni].num_children = static_cast<std::int32_t>(nodes_.size()) - first_child;
    // Push in reverse so that the depth-first order of processing is the key order (not required
    // for correctness; it keeps subtrees contiguous in memory).
    for (std::int32_t c = nodes_[ni].num_children - 1; c >= 0; --c)
      todo.push_back(static_cast<std::uint32_t>(first_child + c));
  }
}

double Tree::refit(std::span<const double> positions, std::span<const double> masses) {
  const auto t0 = Clock::now();
  validate_particles(GravityOptions{}, positions, masses);
  if (masses.size() != order_.size())
    throw GravityError("Tree::refit: particle count differs from the last build (" + std::to_string(masses.size()) +
                       " vs " + std::to_string(order_.size()) + ")");
  load_particles(positions, masses);
  compute_moments();
  collect_groups();  // same ranges, new boxes
  return seconds_since(t0);
}

void Tree::compute_moments() {
  // Children always have larger indices than their parent: a reverse sweep is bottom-up.
  for (std::size_t r = nodes_.size(); r-- > 0;) {
    if (nodes_[r].first_child < 0) {
      leaf_moments(r);
    } else {
      parent_moments(r);
    }
  }
}

void Tree::leaf_moments(std::size_t r) {
  Node& nd = nodes_[r];
  std::array<double, 6>& q = second_moments_[r];
  q.fill(0.0);
  double m = 0, sx = 0, sy = 0, sz = 0;
  const std::uint32_t b = nd.begin, e = nd.begin + nd.count;
  nd.lo = {x_[b], y_[b], z_[b]};
  nd.hi = nd.lo;
  for (std::uint32_t k = b; k < e; ++k) {
    m += m_[k];
    sx += m_[k] * x_[k];
    sy += m_[k] * y_[k];
    sz += m_[k] * z_[k];
    nd.lo = {std::min(nd.lo[0], x_[k]), std::min(nd.lo[1], y_[k]), std::min(nd.lo[2], z_[k])};
    nd.hi = {std::max(nd.hi[0], x_[k]), std::max(nd.hi[1], y_[k]), std::max(nd.hi[2], z_[k])};
  }
  const double corner2 = set_centre_and_size(nd, m, sx, sy, sz);
  // Second moment about the centre of mass and the exact b_max.
  double b2 = 0;
  for (std::uint32_t k = nd.begin; k < nd.begin + nd.count; ++k) {
    const double dx = x_[k] - nd.cx, dy = y_[k] - nd.cy, dz = z_[k] - nd.cz;
    q[0] += m_[k] * dx * dx;
    q[1] += m_[k] * dx * dy;
    q[2] += m_[k] * dx * dz;
    q[3] += m_[k] * dy * dy;
    q[4] += m_[k] * dy * dz;
    q[5] += m_[k] * dz * dz;
    b2 = std::max(b2, dx * dx + dy * dy + dz * dz);
  }
  nd.bmax = std::sqrt(std::min(b2, corner2)) * kBmaxSafety;
}

void Tree::parent_moments(std::size_t r) {
  Node& nd = nodes_[r];
  std::array<double, 6>& q = second_moments_[r];
  q.fill(0.0);
  double m = 0, sx = 0, sy = 0, sz = 0;
  const Node& c0 = nodes_[static_cast<std::size_t>(nd.first_child)];
  nd.lo = c0.lo;
  nd.hi = c0.hi;
  for (std::int32_t c = 0; c < nd.num_children; ++c) {
    const Node& ch = nodes_[static_cast<std::size_t>(nd.first_child) + static_cast<std::size_t>(c)];
    m += ch.mass;
    sx += ch.mass * ch.cx;
    sy += ch.mass * ch.cy;
    sz += ch.mass * ch.cz;
    for (int d = 0; d < 3; ++d) {
      nd.lo[d] = std::min(nd.lo[d], ch.lo[d]);
      nd.hi[d] = std::max(nd.hi[d], ch.hi[d]);
    }
  }
  const double corner2 = set_centre_and_size(nd, m, sx, sy, sz);
  // Parallel-axis theorem: M = sum_c [M_c + m_c d_c d_c^T], d_c = c_c - c.
  double bound = 0;
  for (std::int32_t c = 0; c < nd.num_children; ++c) {
    const auto ci = static_cast<std::size_t>(nd.first_child) + static_cast<std::size_t>(c);
    const Node& ch = nodes_[ci];
    const std::array<double, 6>& qc = second_moments_[ci];
    const double dx = ch.cx - nd.cx, dy = ch.cy - nd.cy, dz = ch.cz - nd.cz;
    q[0] += qc[0] + ch.mass * dx * dx;
    q[1] += qc[1] + ch.mass * dx * dy;
    q[2] += qc[2] + ch.mass * dx * dz;
    q[3] += qc[3] + ch.mass * dy * dy;
    q[4] += qc[4] + ch.mass * dy * dz;
    q[5] += qc[5] + ch.mass * dz * dz;
    bound = std::max(bound, std::sqrt(dx * dx + dy * dy + dz * dz) + ch.bmax);
  }
  nd.bmax = std::min(bound, std::sqrt(corner2)) * kBmaxSafety;
}

void Tree::collect_groups() {
  // A node with at most group_size particles (or a leaf) is a group. The children of a larger
  // node are packed: runs of consecutive small children (contiguous particle ranges) are merged
  // while they hold at most group_size particles, so that groups stay close to group_size even
  // where the octree splits into many small children (sparse regions, e.g. a Plummer halo).
  groups_.clear();
  if (nodes_.empty()) return;
  const auto gmax = static_cast<std::uint32_t>(group_size_);
  auto add = [](const Node& nd, Group& g) {
    if (g.count == 0) {
      g.begin = nd.begin;
      g.lo = nd.lo;
      g.hi = nd.hi;
    } else {
      for (int d = 0; d < 3; ++d) {
        g.lo[d] = std::min(g.lo[d], nd.lo[d]);
        g.hi[d] = std::max(g.hi[d], nd.hi[d]);
      }
    }
    g.count += nd.count;
  };
  std::vector<std::uint32_t> todo{0}, big;
  while (!todo.empty()) {
    const Node& nd = nodes_[todo.back()];
    todo.pop_back();
    if (nd.first_child < 0 || nd.count <= gmax) {
      Group g;
      add(nd, g);
      groups_.push_back(g);
      continue;
    }
    Group run;
    big.clear();
    for (std::int32_t c = 0; c < nd.num_children; ++c) {
      const auto ci = static_cast<std::uint32_t>(nd.first_child + c);
      const Node& ch = nodes_[ci];
      if (ch.count > gmax) {  // walked on its own (recursively unless it is a leaf)
        if (run.count > 0) groups_.push_back(run), run = Group{};
        if (ch.first_child < 0) {
          Group g;
          add(ch, g);
          groups_.push_back(g);
        } else {
          big.push_back(ci);
        }
        continue;
      }
      if (run.count > 0 && run.count + ch.count > gmax) groups_.push_back(run), run = Group{};
      add(ch, run);
    }
    if (run.count > 0) groups_.push_back(run);
    for (auto it = big.rbegin(); it != big.rend(); ++it) todo.push_back(*it);
  }
}

double Tree::evaluate(const GravityOptions& options, std::span<double> accelerations,
                      std::span<double> potential) const {
  const auto t0 = Clock::now();
  const std::size_t n = order_.size();
  if (options.order != 1 && options.order != 2)
    throw GravityError("Tree: order must be 1 (monopole) or 2 (quadrupole), got " + std::to_string(options.order));
  if (!(options.theta > 0) || !std::isfinite(options.theta))
    throw GravityError("Tree: theta must be a finite number > 0");
  if (accelerations.size() != 3 * n) throw GravityError("Tree: accelerations must hold 3N values");
  if (!potential.empty() && potential.size() != n) throw GravityError("Tree: potential must be empty or hold N values");
  stats_ = Stats{};
  stats_.nodes = nodes_.size();
  stats_.leaves = static_cast<std::size_t>(
      std::count_if(nodes_.begin(), nodes_.end(), [](const Node& nd) { return nd.first_child < 0; }));
  stats_.groups = groups_.size();
  if (n == 0) return seconds_since(t0);

  const double eps = options.softening.kind == Softening::Kind::plummer ? options.softening.length : 0.0;
  const double inv_theta = 1.0 / options.theta;
  const bool quadrupole = options.order == 2;
  std::uint64_t p2p_total = 0, m2p_total = 0;

  // Opening criterion (Barnes 1994, "r > l/theta + delta"): a node is used as a multipole for the
  // whole group when the distance from its centre of mass to the group's bounding box exceeds
  //   r_open = max(l / theta + delta, b_max),
  // l = longest side of the node's tight bounding box, delta = distance from the centre of mass to
  // the box centre. The b_max term keeps every target strictly outside the sphere holding the
  // node's particles (the expansion converges and a node never approximates a target's own mass,
  // even for theta >= 1).
  std::vector<WalkNode>& walk = walk_;
  walk.resize(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const Node& nd = nodes_[i];
    walk[i] = {nd.cx,    nd.cy,          nd.cz,          opening_radius2(nd, inv_theta), nd.mass, nd.begin,
               nd.count, nd.first_child, nd.num_children};
  }
  const bool single = options.precision == KernelPrecision::single_precision;
  // Single precision: lengths in units of the root's size, masses in units of the total mass.
  const double length = single && nodes_[0].size > 0 ? nodes_[0].size : 1.0;
  const double mass = single && nodes_[0].mass > 0 ? nodes_[0].mass : 1.0;

#pragma omp parallel reduction(+ : p2p_total, m2p_total) if (n >= kParallelWalkMin)
  {
    InteractionLists<double> lists;
    InteractionLists<float> single_lists;
    std::vector<std::uint32_t> stack;
    // Groups are independent: each target's sums run in the same order whatever thread runs
    // them, so dynamic scheduling keeps results bit-identical for any thread count.
#pragma omp for schedule(dynamic, 4)
    for (std::ptrdiff_t gi = 0; gi < static_cast<std::ptrdiff_t>(groups_.size()); ++gi) {
      const Group& g = groups_[static_cast<std::size_t>(gi)];
      ListUnits units;
      if (single) {
        units = {.ox = 0.5 * (g.lo[0] + g.hi[0]),
                 .oy = 0.5 * (g.lo[1] + g.hi[1]),
                 .oz = 0.5 * (g.lo[2] + g.hi[2]),
                 .inv_length = 1.0 / length,
                 .inv_mass = 1.0 / mass,
                 .inv_moment = 1.0 / (mass * length * length)};
        if (quadrupole)
          gather_interactions<float, true>(g, walk, units, single_lists, stack);
        else
          gather_interactions<float, false>(g, walk, units, single_lists, stack);
        evaluate_group(g, single_lists, units, eps, options.G, accelerations, potential);
      } else {
        if (quadrupole)
          gather_interactions<double, true>(g, walk, units, lists, stack);
        else
          gather_interactions<double, false>(g, walk, units, lists, stack);
        evaluate_group(g, lists, units, eps, options.G, accelerations, potential);
      }
      const std::size_t np = single ? single_lists.pm.size() : lists.pm.size();
      const std::size_t nc = single ? single_lists.cm.size() : lists.cm.size();
      p2p_total += static_cast<std::uint64_t>(np) * g.count;
      m2p_total += static_cast<std::uint64_t>(nc) * g.count;
    }
  }
  stats_.particle_interactions = p2p_total;
  stats_.cell_interactions = m2p_total;
  return seconds_since(t0);
}

namespace {

/// Targets the particle kernel takes per pass over a group's list (p2p_approximate_targets).
constexpr std::size_t kTargetsPerPass = 4;

/// Targets in the lists' units, up to kTargetsPerPass of them.
struct TargetBlock {
  std::array<double, kTargetsPerPass> x{}, y{}, z{};
  std::size_t count = 0;
};

/// The particle kernel by the lists' precision: double (p2p_approximate_targets, the sources read
/// once for four targets) or float (p2p_single, target by target).
inline void tree_p2p(const double* x, const double* y, const double* z, const double* m, std::size_t n,
                     const TargetBlock& targets, double eps2, detail::Accum* acc) {
  detail::p2p_approximate_targets(x, y, z, m, n, targets.x.data(), targets.y.data(), targets.z.data(), targets.count,
                                  eps2, acc);
}
inline void tree_p2p(const float* x, const float* y, const float* z, const float* m, std::size_t n,
                     const TargetBlock& targets, double eps2, detail::Accum* acc) {
  for (std::size_t t = 0; t < targets.count; ++t) {
    detail::p2p_single(x, y, z, m, n, static_cast<float>(targets.x[t]), static_cast<float>(targets.y[t]),
                       static_cast<float>(targets.z[t]), static_cast<float>(eps2), acc[t]);
  }
}
template <typename Lists>
inline void tree_m2p(const Lists& l, const std::array<double, 3>& target, double eps2, detail::Accum& acc) {
  if constexpr (std::is_same_v<typename decltype(l.cm)::value_type, double>) {
    detail::m2p_quadrupole(l.cx.data(), l.cy.data(), l.cz.data(), l.cm.data(), l.xx.data(), l.xy.data(), l.xz.data(),
                           l.yy.data(), l.yz.data(), l.zz.data(), l.cm.size(), target[0], target[1], target[2], eps2,
                           acc);
  } else {
    detail::m2p_quadrupole_single(l.cx.data(), l.cy.data(), l.cz.data(), l.cm.data(), l.xx.data(), l.xy.data(),
                                  l.xz.data(), l.yy.data(), l.yz.data(), l.zz.data(), l.cm.size(),
                                  static_cast<float>(target[0]), static_cast<float>(target[1]),
                                  static_cast<float>(target[2]), static_cast<float>(eps2), acc);
  }
}

}  // namespace

template <typename Real, bool kQuadrupole>
void Tree::gather_interactions(const Group& g, const std::vector<WalkNode>& walk, const ListUnits& units,
                               InteractionLists<Real>& lists, std::vector<std::uint32_t>& stack) const {
  // Quadrupole evaluations cost about two particle interactions: tiny nodes are summed directly.
  constexpr std::uint32_t direct_below = kQuadrupole ? 3 : 0;
  // Values as the lists store them (ListUnits); for double the identity, without arithmetic.
  constexpr bool identity = std::is_same_v<Real, double>;
  const auto length = [&](double x, double origin) {
    if constexpr (identity) return x;
    return static_cast<Real>((x - origin) * units.inv_length);
  };
  const auto scaled = [&](double value, double scale) {
    if constexpr (identity) return value;
    return static_cast<Real>(value * scale);
  };
  const auto point = [&](double x, double y, double z, double m) {
    lists.px.push_back(length(x, units.ox));
    lists.py.push_back(length(y, units.oy));
    lists.pz.push_back(length(z, units.oz));
    lists.pm.push_back(scaled(m, units.inv_mass));
  };
  const auto push_particles = [&](std::uint32_t b, std::uint32_t count) {
    if constexpr (identity) {  // copy the ranges
      lists.px.insert(lists.px.end(), x_.begin() + b, x_.begin() + b + count);
      lists.py.insert(lists.py.end(), y_.begin() + b, y_.begin() + b + count);
      lists.pz.insert(lists.pz.end(), z_.begin() + b, z_.begin() + b + count);
      lists.pm.insert(lists.pm.end(), m_.begin() + b, m_.begin() + b + count);
    } else {
      for (std::uint32_t k = b; k < b + count; ++k) point(x_[k], y_[k], z_[k], m_[k]);
    }
  };
  lists.clear();
  stack.clear();
  stack.push_back(0);
  while (!stack.empty()) {
    const std::size_t ni = stack.back();
    const WalkNode& nd = walk[ni];
    stack.pop_back();
    if (dist2_point_box(nd.cx, nd.cy, nd.cz, g.lo, g.hi) > nd.r_open2) {  // well separated from every target
      if constexpr (!kQuadrupole) {
        point(nd.cx, nd.cy, nd.cz, nd.mass);
      } else if (nd.count < direct_below) {
        push_particles(nd.begin, nd.count);
      } else {
        const std::array<double, 6>& q = second_moments_[ni];
        lists.cx.push_back(length(nd.cx, units.ox));
        lists.cy.push_back(length(nd.cy, units.oy));
        lists.cz.push_back(length(nd.cz, units.oz));
        lists.cm.push_back(scaled(nd.mass, units.inv_mass));
        lists.xx.push_back(scaled(q[0], units.inv_moment));
        lists.xy.push_back(scaled(q[1], units.inv_moment));
        lists.xz.push_back(scaled(q[2], units.inv_moment));
        lists.yy.push_back(scaled(q[3], units.inv_moment));
        lists.yz.push_back(scaled(q[4], units.inv_moment));
        lists.zz.push_back(scaled(q[5], units.inv_moment));
      }
    } else if (nd.first_child < 0) {
      push_particles(nd.begin, nd.count);
    } else {
      for (std::int32_t c = nd.num_children - 1; c >= 0; --c)
        stack.push_back(static_cast<std::uint32_t>(nd.first_child + c));
    }
  }
}

template <typename Real>
void Tree::evaluate_group(const Group& g, const InteractionLists<Real>& lists, const ListUnits& units, double eps,
                          double G, std::span<double> accelerations, std::span<double> potential) const {
  // In the lists' units (identity for double): sum m r / r^3 scales back by M / L^2, sum m / r by
  // M / L (ListUnits).
  const double inv_mass = units.inv_mass, inv_length = units.inv_length;
  const double to_acceleration = -G / inv_mass * inv_length * inv_length;
  const double to_potential = -G / inv_mass * inv_length;
  const double eps_scaled = eps * inv_length;
  const double eps2 = eps_scaled * eps_scaled;
  const std::size_t np = lists.pm.size(), nc = lists.cm.size();
  for (std::uint32_t first = g.begin; first < g.begin + g.count; first += kTargetsPerPass) {
    TargetBlock targets;
    targets.count = std::min<std::size_t>(kTargetsPerPass, g.begin + g.count - first);
    for (std::size_t t = 0; t < targets.count; ++t) {
      const std::size_t k = first + t;
      targets.x[t] = (x_[k] - units.ox) * inv_length;
      targets.y[t] = (y_[k] - units.oy) * inv_length;
      targets.z[t] = (z_[k] - units.oz) * inv_length;
    }
    std::array<detail::Accum, kTargetsPerPass> acc;
    tree_p2p(lists.px.data(), lists.py.data(), lists.pz.data(), lists.pm.data(), np, targets, eps2, acc.data());
    for (std::size_t t = 0; t < targets.count; ++t) {
      const std::size_t k = first + t;
      if (nc > 0) tree_m2p(lists, {targets.x[t], targets.y[t], targets.z[t]}, eps2, acc[t]);
      // The target's own leaf is always opened (it is within b_max of the node's centre), so
      // with softening its self term m_k / eps is in acc.phi: remove it.
      if (eps2 > 0) acc[t].phi -= m_[k] * inv_mass / eps_scaled;
      const std::size_t o = order_[k];
      accelerations[3 * o] = to_acceleration * acc[t].ax;
      accelerations[3 * o + 1] = to_acceleration * acc[t].ay;
      accelerations[3 * o + 2] = to_acceleration * acc[t].az;
      if (!potential.empty()) potential[o] = to_potential * acc[t].phi;
    }
  }
}

}  // namespace rubble::gravity
