// core/shapes.hpp: IndexLists (the flat storage of polyhedron faces and vertex neighbours) reads
// back exactly the nested lists it was built from, and a built ConvexPolyhedron keeps no spare
// capacity (its footprint is per-grain memory, bench/RESULTS.md "Memory per grain").
#include "core/shapes.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "core/polyhedron.hpp"

namespace rubble {
namespace {

std::vector<std::vector<int>> nested(const IndexLists& lists) {
  std::vector<std::vector<int>> out;
  for (const std::span<const int> list : lists) out.emplace_back(list.begin(), list.end());
  return out;
}

// Reference: the nested vectors themselves (lists of different lengths, one empty).
TEST(IndexLists, ReadsBackTheNestedLists) {
  const std::vector<std::vector<int>> reference = {{0, 1, 2}, {}, {3, 4, 5, 6, 7}, {8}};
  const IndexLists lists(reference);
  ASSERT_EQ(lists.size(), 4u);
  EXPECT_FALSE(lists.empty());
  EXPECT_EQ(nested(lists), reference);
  EXPECT_EQ(lists.to_nested(), reference);
  EXPECT_EQ(lists[2].size(), 5u);
  EXPECT_EQ(lists[2][4], 7);
  EXPECT_TRUE(lists[1].empty());
  EXPECT_EQ(lists.indices.size(), 9u);  // one array, no per-list block
  EXPECT_EQ(IndexLists({{0, 1, 2}, {}, {3, 4, 5, 6, 7}, {8}}), lists);
  EXPECT_TRUE(IndexLists().empty());
}

TEST(IndexLists, EditsInPlacePushAndPop) {
  IndexLists lists{{0, 1, 2}, {3, 4, 5}};
  for (const std::span<int> list : lists) std::reverse(list.begin(), list.end());
  EXPECT_EQ(lists.to_nested(), (std::vector<std::vector<int>>{{2, 1, 0}, {5, 4, 3}}));
  lists[0][1] = 9;
  lists.push_back(std::vector<int>{6, 7});
  EXPECT_EQ(lists.to_nested(), (std::vector<std::vector<int>>{{2, 9, 0}, {5, 4, 3}, {6, 7}}));
  lists.pop_back();
  lists.pop_back();
  EXPECT_EQ(lists.to_nested(), (std::vector<std::vector<int>>{{2, 9, 0}}));
  EXPECT_NE(lists, IndexLists({{2, 9, 0}, {}}));
}

// A square pyramid: the neighbours of each vertex are the other ends of its edges (independent
// reference: the edge list), the apex has 4, each base corner 3; every array is exactly full.
TEST(IndexLists, PolyhedronNeighboursMatchTheEdgesAndNoSpareCapacity) {
  const std::vector<Vec3> vertices = {Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0), Vec3(0, 0, 1.5)};
  const std::vector<std::vector<int>> faces = {{0, 3, 2, 1}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}};
  const ConvexPolyhedron shape = make_convex_polyhedron(vertices, faces);
  ASSERT_EQ(shape.vertex_neighbours.size(), 5u);
  for (std::size_t v = 0; v < 5; ++v) {
    std::vector<int> expected;
    for (const auto& [i, j] : shape.edges) {
      if (i == static_cast<int>(v)) expected.push_back(j);
      if (j == static_cast<int>(v)) expected.push_back(i);
    }
    std::vector<int> got(shape.vertex_neighbours[v].begin(), shape.vertex_neighbours[v].end());
    EXPECT_EQ(got, expected) << "vertex " << v;
  }
  EXPECT_EQ(shape.vertex_neighbours[4].size(), 4u);
  EXPECT_EQ(shape.faces.to_nested(), faces);
  EXPECT_EQ(shape.faces.indices.capacity(), shape.faces.indices.size());
  EXPECT_EQ(shape.vertex_neighbours.indices.capacity(), shape.vertex_neighbours.indices.size());
  EXPECT_EQ(shape.edges.capacity(), shape.edges.size());
  EXPECT_EQ(shape.edge_faces.capacity(), shape.edge_faces.size());
  EXPECT_EQ(shape.face_normals.capacity(), shape.face_normals.size());
  EXPECT_EQ(shape.vertices.capacity(), shape.vertices.size());
}

}  // namespace
}  // namespace rubble
