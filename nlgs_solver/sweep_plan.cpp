// The sweep order of a step (nlgs_solver/README.md, "Sweep order and threads"): the contacts'
// moving bodies on a Morton (Z-order) grid, cut into spatial blocks of equal contact counts, a
// binary tree over the blocks, and each contact in the group of the lowest tree node holding its
// moving bodies. Fixed by the data and the block count alone, never by the thread count, since
// Gauss-Seidel's result depends on the order.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/parallel.hpp"
#include "nlgs_solver/nlgs.hpp"

namespace rubble {
namespace {

/// Spreads the low 21 bits of x to every third bit (bit i goes to bit 3i), for Morton keys.
std::uint64_t spread_bits(std::uint64_t x) {
  x &= 0x1fffffULL;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

/// Morton (Z-order) keys of points quantised on 2^21 cells per axis of a cube: points near each
/// other in space mostly get near keys, so a sweep in key order reuses the bodies it just touched
/// (cache) and a contiguous key range is a compact region (few contacts on its boundary).
struct MortonGrid {
  Vec3 lower = Vec3::Zero();     ///< the cube's lowest corner
  double cells_per_metre = 0.0;  ///< 0 when every point is the same

  /// The Morton key of p (points outside the cube are clamped onto it).
  std::uint64_t key(const Vec3& p) const {
    constexpr double top = 2097151.0;  // 2^21 - 1
    std::uint64_t key = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const double cell = std::clamp((p[axis] - lower[axis]) * cells_per_metre, 0.0, top);
      key |= spread_bits(static_cast<std::uint64_t>(cell)) << axis;
    }
    return key;
  }
};

/// Node of the binary tree over the blocks [first, last): split in the middle.
struct BlockNode {
  std::size_t first = 0, last = 0;  ///< leaves (blocks) below this node
  int height = 0;                   ///< 0 for a leaf
  std::size_t left = 0, right = 0;  ///< children (node indices) of an inner node
};

/// Appends the tree over blocks [first, last) to `nodes` (pre-order); returns its root's index.
std::size_t build_block_tree(std::vector<BlockNode>& nodes, std::size_t first, std::size_t last) {
  const std::size_t self = nodes.size();
  nodes.push_back({first, last, 0, 0, 0});
  if (last - first > 1) {
    const std::size_t middle = first + (last - first) / 2;
    const std::size_t left = build_block_tree(nodes, first, middle);
    const std::size_t right = build_block_tree(nodes, middle, last);
    nodes[self].left = left;
    nodes[self].right = right;
    nodes[self].height = 1 + std::max(nodes[left].height, nodes[right].height);
  }
  return self;
}

/// The lowest node whose blocks include both block i and block j.
std::size_t common_node(const std::vector<BlockNode>& nodes, std::size_t i, std::size_t j) {
  std::size_t node = 0;
  while (nodes[node].last - nodes[node].first > 1) {
    const std::size_t middle = nodes[nodes[node].left].last;
    if (i < middle && j < middle)
      node = nodes[node].left;
    else if (i >= middle && j >= middle)
      node = nodes[node].right;
    else
      break;
  }
  return node;
}

/// The tree over the blocks with its nodes numbered as groups: by (height, first block), so that
/// the groups come phase by phase, the leaves first and the root last.
struct BlockTree {
  std::vector<BlockNode> nodes;            ///< pre-order, the root first
  std::vector<std::size_t> by_phase;       ///< group g is node by_phase[g]
  std::vector<std::size_t> group_of_node;  ///< the inverse of by_phase
};

/// The tree over `blocks` blocks and its group numbering.
BlockTree make_block_tree(std::size_t blocks) {
  BlockTree tree;
  build_block_tree(tree.nodes, 0, blocks);
  const std::vector<BlockNode>& nodes = tree.nodes;
  tree.by_phase.resize(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) tree.by_phase[i] = i;
  std::sort(tree.by_phase.begin(), tree.by_phase.end(), [&](std::size_t x, std::size_t y) {
    return std::pair(nodes[x].height, nodes[x].first) < std::pair(nodes[y].height, nodes[y].first);
  });
  tree.group_of_node.resize(nodes.size());
  for (std::size_t g = 0; g < tree.by_phase.size(); ++g) tree.group_of_node[tree.by_phase[g]] = g;
  return tree;
}

/// The contacts' moving bodies in order of first appearance, and per body (indexed by body) the
/// number of contact ends it carries: the weight that balances the blocks.
struct MovingBodies {
  std::vector<std::size_t> bodies;  ///< model indices, in order of first appearance in the contacts
  std::vector<std::size_t> ends;    ///< per model body, its contact ends (0 for walls and free bodies)
};

/// The moving bodies of `contacts` and their contact-end counts.
MovingBodies moving_bodies(const Model& model, const ContactList& contacts) {
  MovingBodies out;
  out.ends.assign(model.body_count(), 0);
  for (const Contact& c : contacts) {
    for (const std::size_t body : {std::size_t{c.id.body_a}, std::size_t{c.id.body_b}}) {
      if (model.is_fixed(body)) continue;
      if (out.ends[body]++ == 0) out.bodies.push_back(body);
    }
  }
  return out;
}

/// The grid over a cube around the moving bodies' centres and the contact points.
MortonGrid bounding_grid(const State& state, const std::vector<std::size_t>& bodies, const ContactList& contacts) {
  MortonGrid grid;
  Vec3 lower = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 upper = -lower;
  for (const std::size_t body : bodies) {
    lower = lower.cwiseMin(state.position[body]);
    upper = upper.cwiseMax(state.position[body]);
  }
  for (const Contact& c : contacts) {
    lower = lower.cwiseMin(c.point);
    upper = upper.cwiseMax(c.point);
  }
  if (!contacts.empty()) {
    const double extent = (upper - lower).maxCoeff();
    grid.lower = lower;
    grid.cells_per_metre = extent > 0.0 ? 2097151.0 / extent : 0.0;
  }
  return grid;
}

/// Bodies in Morton order (ties by index) into plan.body_order, cut into blocks of equal
/// contact-end counts: a body's block is floor(ends before it x blocks / all ends), so blocks are
/// contiguous key ranges. Returns each body's block (indexed by body; only the moving bodies' are
/// meaningful).
std::vector<std::size_t> assign_blocks(const State& state, const MortonGrid& grid, const MovingBodies& moving,
                                       std::size_t blocks, SweepPlan& plan) {
  std::vector<std::pair<std::uint64_t, std::size_t>> sorted;
  sorted.reserve(moving.bodies.size());
  std::size_t total_ends = 0;
  for (const std::size_t body : moving.bodies) {
    sorted.emplace_back(grid.key(state.position[body]), body);
    total_ends += moving.ends[body];
  }
  std::sort(sorted.begin(), sorted.end());
  plan.body_order.reserve(sorted.size());
  for (const auto& [key, body] : sorted) plan.body_order.push_back(body);
  std::vector<std::size_t> block_of(moving.ends.size(), 0);
  std::size_t ends_before = 0;
  for (const auto& [key, body] : sorted) {
    block_of[body] = ends_before * blocks / total_ends;
    ends_before += moving.ends[body];
  }
  return block_of;
}

/// plan.order and plan.group_start: each contact in the group of the lowest node holding all its
/// moving bodies (the root if none moves), within a group in the Morton order of the contact
/// points (ties by index). A counting sort by group, then each group sorted on its own
/// (concurrently).
void order_contacts(const Model& model, const ContactList& contacts, const MortonGrid& grid, const BlockTree& tree,
                    const std::vector<std::size_t>& block_of, SweepPlan& plan) {
  const std::vector<BlockNode>& nodes = tree.nodes;
  const auto n = static_cast<std::ptrdiff_t>(contacts.size());
  const bool parallel = n >= min_parallel_items;
  std::vector<std::size_t> group_of(contacts.size());
  std::vector<std::uint64_t> point_key(contacts.size());
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const std::size_t a = contacts[k].id.body_a, b = contacts[k].id.body_b;
    const bool a_moves = !model.is_fixed(a), b_moves = !model.is_fixed(b);
    std::size_t node = 0;
    if (a_moves || b_moves) {
      const std::size_t block_a = a_moves ? block_of[a] : block_of[b];
      const std::size_t block_b = b_moves ? block_of[b] : block_of[a];
      node = common_node(nodes, std::min(block_a, block_b), std::max(block_a, block_b));
    }
    group_of[k] = tree.group_of_node[node];
    point_key[k] = grid.key(contacts[k].point);
  }
  plan.group_start.assign(nodes.size() + 1, 0);
  for (const std::size_t g : group_of) ++plan.group_start[g + 1];
  for (std::size_t g = 0; g < nodes.size(); ++g) plan.group_start[g + 1] += plan.group_start[g];
  plan.order.resize(contacts.size());
  std::vector<std::size_t> cursor(plan.group_start.begin(), plan.group_start.end() - 1);
  for (std::size_t k = 0; k < contacts.size(); ++k) plan.order[cursor[group_of[k]]++] = k;
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
  for (std::ptrdiff_t g = 0; g < static_cast<std::ptrdiff_t>(nodes.size()); ++g) {
    const auto first = plan.order.begin() + static_cast<std::ptrdiff_t>(plan.group_start[static_cast<std::size_t>(g)]);
    const auto last =
        plan.order.begin() + static_cast<std::ptrdiff_t>(plan.group_start[static_cast<std::size_t>(g) + 1]);
    std::sort(first, last,
              [&](std::size_t x, std::size_t y) { return std::pair(point_key[x], x) < std::pair(point_key[y], y); });
  }
}

/// plan.phase_start (groups of equal height) and plan.parent_group from the tree.
void link_groups(const BlockTree& tree, SweepPlan& plan) {
  const std::vector<BlockNode>& nodes = tree.nodes;
  plan.phase_start.push_back(0);
  for (std::size_t g = 1; g < nodes.size(); ++g) {
    if (nodes[tree.by_phase[g]].height != nodes[tree.by_phase[g - 1]].height) plan.phase_start.push_back(g);
  }
  plan.phase_start.push_back(nodes.size());
  plan.parent_group.assign(nodes.size(), nodes.size());
  for (const BlockNode& node : nodes) {
    if (node.last - node.first == 1) continue;
    const std::size_t self = tree.group_of_node[static_cast<std::size_t>(&node - nodes.data())];
    plan.parent_group[tree.group_of_node[node.left]] = self;
    plan.parent_group[tree.group_of_node[node.right]] = self;
  }
}

}  // namespace

SweepPlan plan_sweep(const Model& model, const State& state, const ContactList& contacts, int block_count) {
  if (block_count < 1) {
    throw std::invalid_argument("plan_sweep: block_count must be at least 1, got " + std::to_string(block_count));
  }
  const auto blocks = static_cast<std::size_t>(block_count);
  const MovingBodies moving = moving_bodies(model, contacts);
  const MortonGrid grid = bounding_grid(state, moving.bodies, contacts);
  SweepPlan plan;
  const std::vector<std::size_t> block_of = assign_blocks(state, grid, moving, blocks, plan);
  const BlockTree tree = make_block_tree(blocks);
  order_contacts(model, contacts, grid, tree, block_of, plan);
  link_groups(tree, plan);
  return plan;
}

}  // namespace rubble
