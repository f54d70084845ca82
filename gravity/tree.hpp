#pragma once
// Barnes-Hut octree over Morton-sorted particles, with monopole and quadrupole moments and a
// group walk (targets that are close in the Morton order share one interaction list).
//
// Typical use (and what compute_field() does for Method::tree):
//   Tree tree(options.leaf_size, options.group_size);
//   tree.build(positions, masses);                       // sort + nodes + moments
//   tree.evaluate(options, accelerations, potential);    // walk + kernels
// When particles moved a little, tree.refit(positions, masses) keeps the order and the topology
// and only recomputes boxes and moments (still exact criterion, somewhat more interactions).

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "gravity/gravity.hpp"

namespace rubble::gravity {

/// A Barnes-Hut octree: particles are reordered along a Morton (Z-order) curve so that every node
/// owns a contiguous range of them. Build is parallel in its keys, sort and particle gather (from
/// 2^18 particles) and sequential in its nodes and moments, and fully deterministic (the same tree
/// for any thread count); evaluate() is parallel over groups of targets.
class Tree {
 public:
  /// One octree node. Children of a node are contiguous in the node array, after their parent.
  struct Node {
    double cx = 0, cy = 0, cz = 0;     ///< centre of mass [m] (box centre if the mass is zero)
    double mass = 0;                   ///< total mass [kg]
    double bmax = 0;                   ///< upper bound of |x_k - c| over the node's particles [m]
    double size = 0;                   ///< longest side of the tight bounding box [m]
    double delta = 0;                  ///< distance from the centre of mass to the box centre [m]
    std::array<double, 3> lo{}, hi{};  ///< tight bounding box of the node's particles [m]
    std::uint32_t begin = 0;           ///< first particle (in sorted order)
    std::uint32_t count = 0;           ///< number of particles
    std::int32_t first_child = -1;     ///< index of the first child, -1 for a leaf
    std::int32_t num_children = 0;     ///< number of (non-empty) children, 0 for a leaf
  };

  /// Targets that walk the tree together: a contiguous range of sorted particles and the tight
  /// box of their positions. A group is the node with at most group_size particles, a run of small
  /// sibling nodes packed up to group_size, or a leaf larger than that (coincident particles).
  struct Group {
    std::uint32_t begin = 0;           ///< first target (in sorted order)
    std::uint32_t count = 0;           ///< number of targets
    std::array<double, 3> lo{}, hi{};  ///< tight bounding box of the targets [m]
  };

  /// Work counters of the last evaluate() (summed over targets).
  struct Stats {
    std::size_t nodes = 0;                    ///< nodes in the tree
    std::size_t leaves = 0;                   ///< leaf nodes
    std::size_t groups = 0;                   ///< target groups walked
    std::uint64_t particle_interactions = 0;  ///< target-particle pairs (P2P)
    std::uint64_t cell_interactions = 0;      ///< target-node multipole evaluations (M2P)
  };

  /// leaf_size: max particles per leaf (>= 1); group_size: max targets per walk group (>= 1).
  explicit Tree(int leaf_size = 16, int group_size = 64);

  /// Max particles per leaf, as constructed.
  int leaf_size() const { return leaf_size_; }
  /// Max targets per walk group, as constructed.
  int group_size() const { return group_size_; }

  /// Builds the tree (Morton keys, stable radix sort, nodes, moments). positions: 3N, masses: N,
  /// both finite, masses >= 0. Returns the wall-clock seconds spent. Throws GravityError.
  double build(std::span<const double> positions, std::span<const double> masses);

  /// Keeps the particle order and the node topology of the last build() and recomputes the
  /// positions, masses, boxes and moments. Same N required. Returns the seconds spent.
  double refit(std::span<const double> positions, std::span<const double> masses);

  /// Field of all particles on all particles (self excluded) with options.theta, options.order,
  /// options.softening and options.G. accelerations: 3N, potential: N or empty. Returns seconds.
  double evaluate(const GravityOptions& options, std::span<double> accelerations, std::span<double> potential) const;

  /// Number of particles of the last build().
  std::size_t size() const { return order_.size(); }
  /// Nodes, root first (empty when N == 0).
  const std::vector<Node>& nodes() const { return nodes_; }
  /// order()[k] = index (in the caller's arrays) of the k-th particle along the Morton curve.
  const std::vector<std::uint32_t>& order() const { return order_; }
  /// Counters of the last evaluate().
  const Stats& stats() const { return stats_; }
  /// Target groups of the last build() (or refit()), in walk order (tests/gravity/test_cuda.cpp
  /// compares the groups of the tree built on the GPU with them).
  const std::vector<Group>& groups() const { return groups_; }
  /// Second moments M_ab = sum_k m_k (x_k - c)_a (x_k - c)_b of each node about its centre of mass,
  /// as Mxx Mxy Mxz Myy Myz Mzz [kg m^2], indexed like nodes().
  const std::vector<std::array<double, 6>>& second_moments() const { return second_moments_; }

  /// Corner lo and longest side `extent` of the particles' bounding box (positions: 3N, N >= 1):
  /// the cube whose grid gives the Morton keys (gravity/morton.hpp). On all threads from 2^18
  /// particles; min and max are exact, so the result does not depend on the threads.
  static void bounding_cube(std::span<const double> positions, std::array<double, 3>& lo, double& extent);

  /// Squared opening radius of a node for opening angle theta: max(l / theta + delta, b_max)^2
  /// (gravity/README.md, "Opening criterion"). A node is accepted as a multipole for a group when
  /// the squared distance from its centre of mass to the group's box exceeds this value
  /// (gravity/cuda/tree_build.cu evaluates the same expression for the GPU walk).
  static double opening_radius2(const Node& node, double inv_theta) {
    const double r_open = std::max(node.bmax, node.size * inv_theta + node.delta);
    return r_open * r_open;
  }

 private:
  /// Copies the particles into x_, y_, z_, m_ in Morton order (order_).
  void load_particles(std::span<const double> positions, std::span<const double> masses);
  /// Splits the root's range of sorted keys into the compressed octree's nodes (nodes_).
  void build_nodes(const std::vector<std::uint64_t>& keys);
  /// Boxes, masses, centres, b_max and second moments of every node, bottom-up.
  void compute_moments();
  /// compute_moments for leaf r, from its particles.
  void leaf_moments(std::size_t r);
  /// compute_moments for node r, from its children (parallel-axis theorem).
  void parent_moments(std::size_t r);
  /// Cuts the particle range into the target groups (groups_).
  void collect_groups();

  int leaf_size_;
  int group_size_;
  std::vector<std::uint32_t> order_;   // sorted -> original index
  std::vector<double> x_, y_, z_, m_;  // particles in Morton order (SoA)
  std::vector<Node> nodes_;
  std::vector<std::array<double, 6>> second_moments_;  // Mxx Mxy Mxz Myy Myz Mzz per node
  std::vector<Group> groups_;
  /// The interaction lists of one group in the kernels' precision (defined in tree.cpp).
  template <typename Real>
  struct InteractionLists;
  /// How gathered values are stored in the lists (defined in tree.cpp).
  struct ListUnits;
  /// What the walk reads of a node, packed, with the opening radius of this evaluation's theta.
  struct WalkNode {
    double cx, cy, cz;  // centre of mass
    double r_open2;     // squared opening radius max(l / theta + delta, b_max)^2
    double mass;
    std::uint32_t begin, count;
    std::int32_t first_child, num_children;
  };
  /// Walks the tree (walk: one entry per node) for group g: fills lists with the particles and the
  /// monopole or quadrupole cells that act on its targets, in `units`; stack is the walk's scratch.
  template <typename Real, bool kQuadrupole>
  void gather_interactions(const Group& g, const std::vector<WalkNode>& walk, const ListUnits& units,
                           InteractionLists<Real>& lists, std::vector<std::uint32_t>& stack) const;
  /// The field of the lists on each target of g (softening length eps, constant G), written at
  /// the targets' input indices.
  template <typename Real>
  void evaluate_group(const Group& g, const InteractionLists<Real>& lists, const ListUnits& units, double eps, double G,
                      std::span<double> accelerations, std::span<double> potential) const;
  // Scratch of build() and evaluate(), members only so that a tree built again and again (one per
  // run: FieldWorkspace) reuses their memory instead of faulting in fresh pages every time.
  std::vector<std::uint64_t> keys_, sort_keys_;  // Morton keys (sorted), the radix sort's buffer
  std::vector<std::uint32_t> sort_order_;        // the radix sort's buffer for order_
  mutable std::vector<WalkNode> walk_;           // evaluate(): the nodes as the walk reads them
  mutable Stats stats_;
};

}  // namespace rubble::gravity
