#pragma once
// Shapes of bodies, described in the body frame (origin at the centre of mass, axes along the
// principal axes of inertia). Walls are bodies of infinite mass with a plane or box shape.
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <iterator>
#include <span>
#include <vector>

#include "core/math.hpp"

namespace rubble {

/// Which shape table a body's shape lives in.
enum class ShapeKind : std::uint8_t {
  sphere,      ///< a ball (grains)
  polyhedron,  ///< a convex polyhedron (grains)
  plane,       ///< an infinite plane (walls only)
  box,         ///< a bounded box, solid inside (walls only)
};

/// A ball of the given radius centred on the body origin.
struct Sphere {
  double radius = 0.0;  ///< m
};

/// An infinite plane through the body origin. The solid fills the half-space behind the plane,
/// grains live on the side its normal points to.
struct Plane {
  Vec3 normal = Vec3::UnitZ();  ///< unit outward normal in the body frame
};

/// A solid rectangular box centred on the body origin, aligned with the body axes.
struct Box {
  Vec3 half_extents = Vec3::Zero();  ///< m, half side lengths along the body axes
};

/// A list of lists of vertex indices (polyhedron faces, vertex neighbours) stored back to back in
/// one array: list i is indices[offsets[i] .. offsets[i+1]). Two heap blocks instead of one per
/// list: a 10-16 vertex grain has ~40 such lists, and one std::vector each cost ~56 bytes of
/// header and malloc chunk on top of its 12-24 bytes of indices (bench/RESULTS.md, "Memory per
/// grain"). Reads like a std::vector<std::vector<int>>: lists[i] is a span of list i, a range-for
/// yields the spans in order.
struct IndexLists {
  std::vector<int> indices;               ///< every list's entries, list after list
  std::vector<std::uint32_t> offsets{0};  ///< list i is indices[offsets[i], offsets[i+1]); offsets[0] = 0

  IndexLists() = default;
  /// From nested lists, e.g. faces = {{0, 1, 2}, {0, 2, 3}, ...}.
  IndexLists(std::initializer_list<std::initializer_list<int>> lists) {
    for (const auto& list : lists) push_back(std::span<const int>(list.begin(), list.size()));
  }
  /// From a vector of lists (the form the mesh readers and builders produce).
  IndexLists(const std::vector<std::vector<int>>& lists) {  // NOLINT: implicit, reads like the nested form
    for (const auto& list : lists) push_back(list);
  }

  /// Number of lists.
  std::size_t size() const { return offsets.size() - 1; }
  /// True if there is no list.
  bool empty() const { return size() == 0; }
  /// List i (read only).
  std::span<const int> operator[](std::size_t i) const {
    return {indices.data() + offsets[i], offsets[i + 1] - offsets[i]};
  }
  /// List i (its entries may be changed, not its length).
  std::span<int> operator[](std::size_t i) { return {indices.data() + offsets[i], offsets[i + 1] - offsets[i]}; }
  /// Appends a list.
  void push_back(std::span<const int> list) {
    indices.insert(indices.end(), list.begin(), list.end());
    offsets.push_back(static_cast<std::uint32_t>(indices.size()));
  }
  /// Removes the last list (there must be one).
  void pop_back() {
    offsets.pop_back();
    indices.resize(offsets.back());
  }
  /// Releases spare capacity (after the last push_back).
  void shrink_to_fit() {
    indices.shrink_to_fit();
    offsets.shrink_to_fit();
  }
  /// The lists as nested vectors (for code that needs to own and edit them).
  std::vector<std::vector<int>> to_nested() const {
    std::vector<std::vector<int>> lists;
    lists.reserve(size());
    for (std::size_t i = 0; i < size(); ++i) lists.emplace_back((*this)[i].begin(), (*this)[i].end());
    return lists;
  }
  /// Same lists, same entries.
  bool operator==(const IndexLists&) const = default;

  /// Iterates over the lists, yielding spans (read only or not after the container's constness).
  template <typename Owner, typename Span>
  struct Iterator {
    using iterator_category = std::forward_iterator_tag;  ///< forward iteration over the lists
    using value_type = Span;                              ///< a list
    using difference_type = std::ptrdiff_t;               ///< distance between lists
    using pointer = void;                                 ///< lists are returned by value
    using reference = Span;                               ///< lists are returned by value
    Owner* owner = nullptr;                               ///< the lists
    std::size_t i = 0;                                    ///< current list
    /// The current list.
    Span operator*() const { return (*owner)[i]; }
    /// Next list.
    Iterator& operator++() {
      ++i;
      return *this;
    }
    /// Next list (post-increment).
    Iterator operator++(int) {
      Iterator old = *this;
      ++i;
      return old;
    }
    /// Same list of the same container.
    bool operator==(const Iterator& other) const { return i == other.i && owner == other.owner; }
  };
  /// Iterator over read-only lists.
  using const_iterator = Iterator<const IndexLists, std::span<const int>>;
  /// Iterator over lists whose entries may change.
  using iterator = Iterator<IndexLists, std::span<int>>;
  /// First list.
  const_iterator begin() const { return {this, 0}; }
  /// Past the last list.
  const_iterator end() const { return {this, size()}; }
  /// First list.
  iterator begin() { return {this, 0}; }
  /// Past the last list.
  iterator end() { return {this, size()}; }
};

/// A convex polyhedron in its body frame (centroid at the origin, principal axes).
/// Faces are lists of vertex indices in counter-clockwise order seen from outside.
/// Build it with make_convex_polyhedron (core/polyhedron.hpp), which fills every field and
/// releases spare capacity: a scene holds one per grain, so its heap footprint is the per-grain
/// memory (flat arrays only, 9 heap blocks).
struct ConvexPolyhedron {
  std::vector<Vec3> vertices;                         ///< m, body frame
  IndexLists faces;                                   ///< per face: vertex indices, CCW from outside
  std::vector<Vec3> face_normals;                     ///< unit outward normals, one per face
  std::vector<std::pair<int, int>> edges;             ///< each undirected edge once (i < j)
  std::vector<double> face_offsets;                   ///< m, d_f = max over the vertices of n_f . x (supporting plane)
  std::vector<std::pair<int, int>> edge_faces;        ///< per edge: the face on its left (i -> j CCW) and on its right
  IndexLists vertex_neighbours;                       ///< per vertex: the vertices sharing an edge with it
  Vec3 box_min = Vec3::Zero();                        ///< m, body-frame bounding box, lower corner
  Vec3 box_max = Vec3::Zero();                        ///< m, body-frame bounding box, upper corner
  double bounding_radius = 0.0;                       ///< m, max |x| over the vertices (sphere about the centroid)
  double volume = 0.0;                                ///< m^3
  Vec3 principal_inertia_per_density = Vec3::Zero();  ///< m^5, diagonal of the inertia tensor / density
};

}  // namespace rubble
