// Self-intersection counts: hand-made pairs (crossing, coplanar, touching,
// seam duplicates) and, for each adjacency class of CGAL's definition, pairs
// with known answers (sharing an edge, a vertex, a whole face; a flipped fan;
// degenerate triangles), the exact triangle test against separating axes on
// grid triangles, the hierarchy against all pairs on jittered cylinders, the
// procedural rigs at rest and a cylinder bent by linear blend skinning, the
// pairs new against the rest pose, and bad input. CGAL itself is the
// reference in self_intersection_cgal_test.cpp.
#include "isk/tools/self_intersection.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "isk/core/error.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/procedural.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using test::positionsOf;
using test::trianglesOf;

using Pairs = std::vector<std::pair<int, int>>;

// Two triangles of six separate vertices (no shared index).
int countPair(const std::vector<Eigen::Vector3f>& six) {
  return countSelfIntersections(positionsOf(six),
                                trianglesOf({{0, 1, 2}, {3, 4, 5}}));
}

TEST(SelfIntersection, DisjointTrianglesDoNotCount) {
  EXPECT_EQ(
      countPair(
          {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}}),
      0);
  // Boxes overlap, triangles do not: b passes beside a's hypotenuse.
  EXPECT_EQ(countPair({{0, 0, 0},
                       {2, 0, 0},
                       {0, 2, 0},
                       {1.5f, 1.5f, -1},
                       {1.5f, 1.5f, 1},
                       {3, 3, 0}}),
            0);
  EXPECT_EQ(countSelfIntersections(Matrix3Xf(0, 3), TriangleMatrix(0, 3)), 0);
}

TEST(SelfIntersection, CrossingTrianglesCountOnce) {
  // A third, far triangle makes sure the pair is reported by index.
  const Matrix3Xf positions = positionsOf({{0, 0, 0},
                                           {2, 0, 0},
                                           {0, 2, 0},
                                           {9, 9, 9},
                                           {10, 9, 9},
                                           {9, 10, 9},
                                           {0.5f, 0.5f, -1},
                                           {0.5f, 0.5f, 1},
                                           {-1, -1, 0.2f}});
  const TriangleMatrix triangles =
      trianglesOf({{0, 1, 2}, {3, 4, 5}, {6, 7, 8}});
  Pairs pairs;
  EXPECT_EQ(countSelfIntersections(positions, triangles, nullptr, &pairs), 1);
  EXPECT_EQ(pairs, (Pairs{{0, 2}}));
}

// The pairs of a mesh, sorted.
Pairs pairsOf(const std::vector<Eigen::Vector3f>& points,
              const std::vector<Eigen::Vector3i>& corners,
              const std::vector<int>* groups = nullptr) {
  Pairs pairs;
  countSelfIntersections(positionsOf(points), trianglesOf(corners), groups,
                         &pairs);
  return pairs;
}

// Adjacent triangles folded through each other count (CGAL's definition);
// the same geometry without the shared index counts too (touching).
TEST(SelfIntersection, AdjacentTrianglesFoldedThroughEachOtherCount) {
  // Sharing vertex 0, the second triangle pierces the first's interior.
  const std::vector<Eigen::Vector3f> vertex_fold = {
      {0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {1, 0.5f, 1}, {1, 0.5f, -1}};
  EXPECT_EQ(countSelfIntersections(positionsOf(vertex_fold),
                                   trianglesOf({{0, 1, 2}, {0, 3, 4}})),
            1);
  EXPECT_EQ(countPair({vertex_fold[0], vertex_fold[1], vertex_fold[2],
                       vertex_fold[0], vertex_fold[3], vertex_fold[4]}),
            1);
  // Sharing edge 0-1, the second triangle folded flat onto the first.
  const std::vector<Eigen::Vector3f> edge_fold = {
      {0, 0, 0}, {2, 0, 0}, {1, 2, 0}, {1, 1, 0}};
  EXPECT_EQ(countSelfIntersections(positionsOf(edge_fold),
                                   trianglesOf({{0, 1, 2}, {0, 1, 3}})),
            1);
  EXPECT_EQ(countPair({edge_fold[0], edge_fold[1], edge_fold[2], edge_fold[0],
                       edge_fold[1], edge_fold[3]}),
            1);
}

// Sharing an edge: only an exactly flat fold (coplanar, both opposite
// vertices on one side of the edge) counts, as in CGAL.
TEST(SelfIntersection, EdgeNeighboursCountOnlyFoldedFlat) {
  const std::vector<Eigen::Vector3i> two = {{0, 1, 2}, {1, 0, 3}};
  // Flat and unfolded: 3 on the other side of edge 0-1.
  EXPECT_EQ(pairsOf({{0, 0, 0}, {2, 0, 0}, {1, 2, 0}, {1, -2, 0}}, two),
            Pairs{});
  // Folded flat: 3 on 2's side, inside the first triangle or beyond it.
  EXPECT_EQ(pairsOf({{0, 0, 0}, {2, 0, 0}, {1, 2, 0}, {1, 1, 0}}, two),
            (Pairs{{0, 1}}));
  EXPECT_EQ(pairsOf({{0, 0, 0}, {2, 0, 0}, {1, 2, 0}, {5, 7, 0}}, two),
            (Pairs{{0, 1}}));
  // Tilted plane x + y + z = 2, folded flat.
  EXPECT_EQ(pairsOf({{2, 0, 0}, {0, 2, 0}, {0, 0, 2}, {1, 0, 1}}, two),
            (Pairs{{0, 1}}));
  // A sharp fold that is not flat: 3 lifted by the smallest float step. The
  // triangles overlap in all but a sliver, yet CGAL does not count them.
  const float lift = std::nextafter(0.f, 1.f);
  EXPECT_EQ(pairsOf({{0, 0, 0}, {2, 0, 0}, {1, 2, 0}, {1, 1, lift}}, two),
            Pairs{});
  EXPECT_EQ(pairsOf({{0, 0, 0}, {2, 0, 0}, {1, 2, 0}, {1, 1, 0.5f}}, two),
            Pairs{});
}

// Sharing one vertex: counted iff the edge of either triangle opposite that
// vertex meets the other triangle.
TEST(SelfIntersection, VertexNeighboursCountWhenAnOppositeEdgeMeetsTheOther) {
  const std::vector<Eigen::Vector3i> two = {{0, 1, 2}, {0, 3, 4}};
  const Eigen::Vector3f o(0, 0, 0), x(2, 0, 0), y(0, 2, 0);
  // Edge 3-4 pierces the first triangle.
  EXPECT_EQ(pairsOf({o, x, y, {1, 0.5f, 1}, {1, 0.5f, -1}}, two),
            (Pairs{{0, 1}}));
  // The same edge beside it (crossing the plane at (1, -1), outside the
  // first's wedge): apart, touching only at the shared vertex.
  EXPECT_EQ(pairsOf({o, x, y, {1, -1, 1}, {1, -1, -1}}, two), Pairs{});
  // Standing up from the shared vertex, above the plane: apart.
  EXPECT_EQ(pairsOf({o, x, y, {1, 0.5f, 1}, {0.5f, 1, 1}}, two), Pairs{});
  // Edge 3-4 ends on the first triangle's edge 1-2 (touching counts).
  EXPECT_EQ(pairsOf({o, x, y, {1, 1, 0}, {1, 0.5f, 1}}, two), (Pairs{{0, 1}}));
  // Coplanar: the second inside the first's wedge, short (its opposite edge
  // lies in the first) or long (the first's opposite edge crosses it).
  EXPECT_EQ(pairsOf({o, x, y, {1, 0.5f, 0}, {0.5f, 1, 0}}, two),
            (Pairs{{0, 1}}));
  EXPECT_EQ(pairsOf({o, x, y, {4, 2, 0}, {2, 4, 0}}, two), (Pairs{{0, 1}}));
  // Coplanar, in the opposite wedge: apart.
  EXPECT_EQ(pairsOf({o, x, y, {-1, -0.5f, 0}, {-0.5f, -1, 0}}, two), Pairs{});
}

// Seam duplicates welded by groups behave like shared vertices, at the
// representative's position.
TEST(SelfIntersection, WeldedSeamDuplicatesActAsSharedVertices) {
  // Vertex 3 is a copy of 0 (vertex fold) or 4, 5 copies of 0, 1 (edge fold).
  const std::vector<Eigen::Vector3f> vertex_apart = {
      {0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 0}, {1, 0.5f, 1}, {0.5f, 1, 1}};
  const std::vector<Eigen::Vector3i> vertex_two = {{0, 1, 2}, {3, 4, 5}};
  const std::vector<int> vertex_groups = {0, 1, 2, 0, 4, 5};
  EXPECT_EQ(coincidentVertexGroups(positionsOf(vertex_apart)), vertex_groups);
  // Unwelded they touch at the vertex; welded they only share it.
  EXPECT_EQ(pairsOf(vertex_apart, vertex_two), (Pairs{{0, 1}}));
  EXPECT_EQ(pairsOf(vertex_apart, vertex_two, &vertex_groups), Pairs{});
  // Welded and pierced.
  std::vector<Eigen::Vector3f> vertex_pierced = vertex_apart;
  vertex_pierced[5] = {1, 0.5f, -1};
  EXPECT_EQ(pairsOf(vertex_pierced, vertex_two, &vertex_groups),
            (Pairs{{0, 1}}));
  // An edge seam folded flat counts welded; unfolded it counts only
  // unwelded (touching along the edge).
  const std::vector<Eigen::Vector3i> edge_two = {{0, 1, 2}, {5, 4, 3}};
  const std::vector<int> edge_groups = {0, 1, 2, 3, 0, 1};
  const std::vector<Eigen::Vector3f> folded = {{0, 0, 0}, {2, 0, 0}, {1, 2, 0},
                                               {1, 1, 0}, {0, 0, 0}, {2, 0, 0}};
  const std::vector<Eigen::Vector3f> unfolded = {
      {0, 0, 0}, {2, 0, 0}, {1, 2, 0}, {1, -1, 0}, {0, 0, 0}, {2, 0, 0}};
  EXPECT_EQ(pairsOf(folded, edge_two, &edge_groups), (Pairs{{0, 1}}));
  EXPECT_EQ(pairsOf(unfolded, edge_two, &edge_groups), Pairs{});
  EXPECT_EQ(pairsOf(unfolded, edge_two), (Pairs{{0, 1}}));
  // The representative's position decides: copies 4, 5 posed elsewhere
  // still weld onto 0, 1 (the second triangle is 1-0-3, folded flat).
  std::vector<Eigen::Vector3f> moved = folded;
  moved[4] = {9, 9, 9};
  moved[5] = {8, 9, 9};
  EXPECT_EQ(pairsOf(moved, edge_two, &edge_groups), (Pairs{{0, 1}}));
  moved[3] = {1, -1, 0};
  EXPECT_EQ(pairsOf(moved, edge_two, &edge_groups), Pairs{});
}

// A flat fan of six triangles around vertex 0 where ring vertex 1 is pulled
// across the centre into triangle 3's sector: triangles 0 and 5, which use
// it, fold over their neighbours (the spike of a bad deformation).
TEST(SelfIntersection, FlippedTriangleInAFanCounts) {
  std::vector<Eigen::Vector3f> points = {{0, 0, 0},  {2, 0, 0},  {1, 2, 0},
                                         {-1, 2, 0}, {-2, 0, 0}, {-1, -2, 0},
                                         {1, -2, 0}};
  std::vector<Eigen::Vector3i> fan;
  for (int k = 0; k < 6; ++k) fan.emplace_back(0, k + 1, (k + 1) % 6 + 1);
  EXPECT_EQ(pairsOf(points, fan), Pairs{});
  points[1] = {-1, -0.5f, 0};
  // 0-1 and 4-5 folded flat over an edge neighbour; 0-2 (0's edge 1-2
  // crosses 2), 0-3 and 3-5 (the moved vertex lies in 3) at the centre.
  EXPECT_EQ(pairsOf(points, fan),
            (Pairs{{0, 1}, {0, 2}, {0, 3}, {3, 5}, {4, 5}}));
  // Not flat: vertex 2 lifted to z = 1, vertex 1 pulled below the plane
  // (z = -1). Triangle 0's outer edge 1-2 now crosses z = 0 at (-0.5, 0.5),
  // inside triangle 2, which shares only the centre with it; the sharp
  // folds over the edges 0-2 and 0-1 do not count.
  points[2] = {1, 2, 1};
  points[1] = {-2, -1, -1};
  EXPECT_EQ(pairsOf(points, fan), (Pairs{{0, 2}}));
}

// A face given twice (either orientation, or through seam copies) counts.
TEST(SelfIntersection, DoubledFaceCounts) {
  const std::vector<Eigen::Vector3f> points = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0},
                                               {0, 0, 0}, {2, 0, 0}, {0, 2, 0}};
  EXPECT_EQ(pairsOf(points, {{0, 1, 2}, {0, 2, 1}}), (Pairs{{0, 1}}));
  EXPECT_EQ(pairsOf(points, {{0, 1, 2}, {1, 2, 0}}), (Pairs{{0, 1}}));
  const std::vector<int> groups = {0, 1, 2, 0, 1, 2};
  EXPECT_EQ(pairsOf(points, {{0, 1, 2}, {3, 5, 4}}, &groups), (Pairs{{0, 1}}));
  EXPECT_EQ(pairsOf(points, {{0, 1, 2}, {3, 5, 4}}), (Pairs{{0, 1}}));
}

TEST(SelfIntersection, CoplanarOverlappingTrianglesCount) {
  EXPECT_EQ(countPair({{0, 0, 0},
                       {2, 0, 0},
                       {0, 2, 0},
                       {0.5f, 0.5f, 0},
                       {2.5f, 0.5f, 0},
                       {0.5f, 2.5f, 0}}),
            1);
  // In the tilted plane x + y + z = 3, one inside the other.
  EXPECT_EQ(
      countPair(
          {{3, 0, 0}, {0, 3, 0}, {0, 0, 3}, {1, 1, 1}, {2, 0, 1}, {1, 0, 2}}),
      1);
  // Coplanar, apart.
  EXPECT_EQ(
      countPair(
          {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 2, 0}, {3, 2, 0}, {2, 3, 0}}),
      0);
}

// Triangles are closed: touching counts (see self_intersection.hpp).
TEST(SelfIntersection, TouchingTrianglesCount) {
  // b's vertex on the midpoint of a's edge, b standing above a's plane.
  EXPECT_EQ(
      countPair(
          {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {1, 0, 0}, {1, -1, 1}, {2, -1, 1}}),
      1);
  // b's vertex on a's interior.
  EXPECT_EQ(countPair({{0, 0, 0},
                       {2, 0, 0},
                       {0, 2, 0},
                       {0.5f, 0.5f, 0},
                       {0, 0, 1},
                       {1, 0, 1}}),
            1);
  // Lifted by the smallest step: apart.
  const float above = std::nextafter(0.f, 1.f);
  EXPECT_EQ(countPair({{0, 0, 0},
                       {2, 0, 0},
                       {0, 2, 0},
                       {0.5f, 0.5f, above},
                       {0, 0, 1},
                       {1, 0, 1}}),
            0);
}

TEST(SelfIntersection, SeamDuplicatesCountOnlyWithoutGroups) {
  // Two triangles on either side of edge 1-2; the second uses copies 3, 4.
  const Matrix3Xf positions = positionsOf(
      {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0.5f}});
  const TriangleMatrix triangles = trianglesOf({{0, 1, 2}, {3, 5, 4}});
  const std::vector<int> groups = coincidentVertexGroups(positions);
  EXPECT_EQ(groups, (std::vector<int>{0, 1, 2, 1, 2, 5}));
  EXPECT_EQ(countSelfIntersections(positions, triangles), 1);
  EXPECT_EQ(countSelfIntersections(positions, triangles, &groups), 0);
}

TEST(SelfIntersection, CoincidentVertexGroupsCompareBits) {
  const Matrix3Xf positions = positionsOf(
      {{1, 2, 3}, {0, 0, 0}, {1, 2, 3}, {-0.f, 0, 0}, {0, 0, 0}, {1, 2, 3}});
  EXPECT_EQ(coincidentVertexGroups(positions),
            (std::vector<int>{0, 1, 0, 3, 1, 0}));
  EXPECT_TRUE(coincidentVertexGroups(Matrix3Xf(0, 3)).empty());
}

// Degenerate triangles take part in no pair and are counted apart.
TEST(SelfIntersection, DegenerateTrianglesAreLeftOutAndCounted) {
  int degenerate = -1;
  // A zero-area sliver (collinear corners) lying across a triangle.
  EXPECT_EQ(countSelfIntersections(positionsOf({{0, 0, 0},
                                                {2, 0, 0},
                                                {0, 2, 0},
                                                {-1, 0.5f, 0},
                                                {0.5f, 0.5f, 0},
                                                {3, 0.5f, 0}}),
                                   trianglesOf({{0, 1, 2}, {3, 4, 5}}), nullptr,
                                   nullptr, &degenerate),
            0);
  EXPECT_EQ(degenerate, 1);
  // A repeated index: a segment piercing the triangle.
  const Matrix3Xf positions = positionsOf({{0, 0, 0},
                                           {2, 0, 0},
                                           {0, 2, 0},
                                           {0.5f, 0.5f, -1},
                                           {0.5f, 0.5f, 1},
                                           {0.5f, 0.5f, 1}});
  EXPECT_EQ(
      countSelfIntersections(positions, trianglesOf({{0, 1, 2}, {3, 3, 4}}),
                             nullptr, nullptr, &degenerate),
      0);
  EXPECT_EQ(degenerate, 1);
  // Two corners welded into one: vertices 4 and 5 are one group, so
  // triangle 3-4-5 collapses (it would pierce the first unwelded).
  const std::vector<int> groups = {0, 1, 2, 3, 4, 4};
  std::vector<std::pair<int, int>> pairs;
  Matrix3Xf apart = positions;
  apart.row(5) << 0.5f, 1.5f, 1;
  const TriangleMatrix three = trianglesOf({{0, 1, 2}, {3, 4, 5}, {0, 3, 4}});
  EXPECT_EQ(countSelfIntersections(apart, three, nullptr, &pairs, &degenerate),
            2);
  EXPECT_EQ(pairs, (Pairs{{0, 1}, {0, 2}}));
  EXPECT_EQ(degenerate, 0);
  EXPECT_EQ(countSelfIntersections(apart, three, &groups, &pairs, &degenerate),
            1);
  EXPECT_EQ(pairs, (Pairs{{0, 2}}));
  EXPECT_EQ(degenerate, 1);
  // All degenerate, and none at all.
  EXPECT_EQ(countSelfIntersections(positions, trianglesOf({{3, 4, 5}}), nullptr,
                                   nullptr, &degenerate),
            0);
  EXPECT_EQ(degenerate, 1);
  EXPECT_EQ(countSelfIntersections(Matrix3Xf(0, 3), TriangleMatrix(0, 3),
                                   nullptr, nullptr, &degenerate),
            0);
  EXPECT_EQ(degenerate, 0);
}

TEST(SelfIntersection, NewPairsAreThoseNotIntersectingAtRest) {
  EXPECT_EQ(newSelfIntersections({{0, 1}, {0, 4}, {2, 3}, {5, 6}},
                                 {{0, 4}, {1, 2}, {5, 6}}),
            (Pairs{{0, 1}, {2, 3}}));
  EXPECT_EQ(newSelfIntersections({}, {{0, 1}}), Pairs{});
  EXPECT_EQ(newSelfIntersections({{0, 1}}, {}), (Pairs{{0, 1}}));
  // Any order in, sorted and without repeats out.
  EXPECT_EQ(newSelfIntersections({{3, 4}, {0, 1}, {3, 4}, {1, 2}}, {{1, 2}}),
            (Pairs{{0, 1}, {3, 4}}));
}

// Independent reference for closed triangles with small integer corners,
// where double arithmetic is exact: disjoint iff some axis separates them
// strictly, among the normals, the edge-edge cross products and the in-plane
// edge normals (those decide coplanar pairs).
bool separatingAxesMeet(const std::vector<Eigen::Vector3f>& six) {
  Eigen::Vector3d a[3], b[3], ea[3], eb[3];
  for (int i = 0; i < 3; ++i) {
    a[i] = six[i].cast<double>();
    b[i] = six[i + 3].cast<double>();
  }
  for (int i = 0; i < 3; ++i) {
    ea[i] = a[(i + 1) % 3] - a[i];
    eb[i] = b[(i + 1) % 3] - b[i];
  }
  const Eigen::Vector3d na = ea[0].cross(ea[1]), nb = eb[0].cross(eb[1]);
  std::vector<Eigen::Vector3d> axes = {na, nb};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) axes.push_back(ea[i].cross(eb[j]));
    axes.push_back(na.cross(ea[i]));
    axes.push_back(nb.cross(eb[i]));
  }
  for (const Eigen::Vector3d& axis : axes) {
    double a_lo = axis.dot(a[0]), a_hi = a_lo, b_lo = axis.dot(b[0]),
           b_hi = b_lo;
    for (int i = 1; i < 3; ++i) {
      a_lo = std::min(a_lo, axis.dot(a[i]));
      a_hi = std::max(a_hi, axis.dot(a[i]));
      b_lo = std::min(b_lo, axis.dot(b[i]));
      b_hi = std::max(b_hi, axis.dot(b[i]));
    }
    if (a_hi < b_lo || b_hi < a_lo) return false;
  }
  return true;
}

// Grid corners make touching, collinear and coplanar configurations common:
// the cases where an inexact test goes wrong.
TEST(SelfIntersection, TriangleTestMatchesSeparatingAxesOnGridTriangles) {
  std::mt19937 random(11);
  std::uniform_int_distribution<int> coordinate(0, 3);
  int checked = 0, meeting = 0;
  for (int trial = 0; trial < 40000; ++trial) {
    // Half the trials in the tilted plane z = 6 - x - y.
    const bool coplanar = trial % 2 == 1;
    std::vector<Eigen::Vector3f> six(6);
    for (auto& p : six) {
      const int x = coordinate(random), y = coordinate(random);
      p = Eigen::Vector3f(x, y, coplanar ? 6 - x - y : coordinate(random));
    }
    const bool degenerate =
        (six[1] - six[0]).cross(six[2] - six[0]).isZero(0.f) ||
        (six[4] - six[3]).cross(six[5] - six[3]).isZero(0.f);
    const int expected = !degenerate && separatingAxesMeet(six) ? 1 : 0;
    ASSERT_EQ(countPair(six), expected)
        << "trial " << trial << ": (" << six[0].transpose() << ") ("
        << six[1].transpose() << ") (" << six[2].transpose() << ") vs ("
        << six[3].transpose() << ") (" << six[4].transpose() << ") ("
        << six[5].transpose() << ")";
    checked += degenerate ? 0 : 1;
    meeting += expected;
  }
  // Both outcomes well represented.
  EXPECT_GT(meeting, checked / 5);
  EXPECT_LT(meeting, checked * 4 / 5);
}

// All pairs, each through a two-triangle call (no hierarchy to speak of) on
// the pair's welded vertices, so that shared vertices stay shared.
Pairs bruteForcePairs(const Matrix3Xf& positions,
                      const TriangleMatrix& triangles,
                      const std::vector<int>* groups) {
  auto group = [&](int v) { return groups ? (*groups)[v] : v; };
  Pairs pairs;
  for (int a = 0; a < triangles.rows(); ++a) {
    for (int b = a + 1; b < triangles.rows(); ++b) {
      std::vector<int> welded;  // local index -> welded vertex
      TriangleMatrix two(2, 3);
      for (int t = 0; t < 2; ++t) {
        for (int c = 0; c < 3; ++c) {
          const int g = group(triangles(t == 0 ? a : b, c));
          auto it = std::find(welded.begin(), welded.end(), g);
          two(t, c) = static_cast<int>(it - welded.begin());
          if (it == welded.end()) welded.push_back(g);
        }
      }
      Matrix3Xf local(static_cast<int>(welded.size()), 3);
      for (size_t v = 0; v < welded.size(); ++v)
        local.row(v) = positions.row(welded[v]);
      if (countSelfIntersections(local, two) == 1) pairs.emplace_back(a, b);
    }
  }
  return pairs;
}

TEST(SelfIntersection, HierarchyMatchesBruteForceOnJitteredCylinders) {
  struct Case {
    int rings, segments;
    float jitter;  // times the radius
    bool seams;    // duplicate a column of vertices, grouped back
  };
  const std::vector<Case> cases = {{4, 6, 0.3f, false},
                                   {6, 8, 0.5f, false},
                                   {8, 12, 0.25f, true},
                                   {10, 10, 0.8f, false},
                                   {12, 16, 0.15f, true}};
  for (size_t m = 0; m < cases.size(); ++m) {
    CylinderRigOptions options;
    options.rings = cases[m].rings;
    options.segments = cases[m].segments;
    options.length = 3.f;
    Mesh mesh = makeCylinderRig(options).mesh;
    std::mt19937 random(100 + static_cast<unsigned>(m));
    std::normal_distribution<float> noise(0.f, cases[m].jitter);
    for (int v = 0; v < mesh.positions.rows(); ++v) {
      for (int k = 0; k < 3; ++k) mesh.positions(v, k) += noise(random);
    }
    // Flatten a few triangles to zero area: collapse one corner onto another.
    for (int f = 5; f < mesh.triangles.rows(); f += 37) {
      mesh.positions.row(mesh.triangles(f, 0)) =
          mesh.positions.row(mesh.triangles(f, 1));
    }
    std::vector<int> groups;
    if (cases[m].seams) {
      // Triangles using vertex s of the first ring use a copy instead.
      const int original = static_cast<int>(mesh.positions.rows());
      mesh.positions.conservativeResize(original + options.segments, 3);
      for (int s = 0; s < options.segments; ++s)
        mesh.positions.row(original + s) = mesh.positions.row(s);
      for (int f = 0; f < mesh.triangles.rows(); f += 2) {
        for (int c = 0; c < 3; ++c) {
          if (mesh.triangles(f, c) < options.segments)
            mesh.triangles(f, c) += original;
        }
      }
      groups = coincidentVertexGroups(mesh.positions);
    }
    const std::vector<int>* group_ptr = cases[m].seams ? &groups : nullptr;
    Pairs actual;
    const int count = countSelfIntersections(mesh.positions, mesh.triangles,
                                             group_ptr, &actual);
    const Pairs expected =
        bruteForcePairs(mesh.positions, mesh.triangles, group_ptr);
    EXPECT_EQ(count, static_cast<int>(actual.size())) << "mesh " << m;
    EXPECT_GT(expected.size(), 0u) << "mesh " << m << " is too tame";
    size_t first = 0;
    while (first < actual.size() && first < expected.size() &&
           actual[first] == expected[first])
      ++first;
    ASSERT_TRUE(first == actual.size() && first == expected.size())
        << "mesh " << m << " (" << mesh.triangles.rows()
        << " triangles): first mismatch at pair " << first << " of "
        << actual.size() << " found and " << expected.size() << " expected: "
        << (first < actual.size() ? std::to_string(actual[first].first) + "-" +
                                        std::to_string(actual[first].second)
                                  : std::string("none"))
        << " vs "
        << (first < expected.size()
                ? std::to_string(expected[first].first) + "-" +
                      std::to_string(expected[first].second)
                : std::string("none"));
  }
}

TEST(SelfIntersection, ProceduralRigsAtRestHaveNone) {
  for (const std::string& name : builtinRigNames()) {
    const Rig rig = makeBuiltinRig(name);
    Pairs pairs;
    EXPECT_EQ(countSelfIntersections(rig.mesh.positions, rig.mesh.triangles,
                                     nullptr, &pairs),
              0)
        << name << ": first pair " << (pairs.empty() ? -1 : pairs[0].first)
        << "-" << (pairs.empty() ? -1 : pairs[0].second);
  }
}

// Skins the cylinder with its second bone rotated about z at the inner joint.
Matrix3Xf bentCylinder(const Rig& rig, SkinningMethod method, float degrees) {
  TransformList locals;
  for (const Joint& joint : rig.skeleton.joints)
    locals.push_back(joint.rest_local);
  locals[1] = locals[1] * Eigen::AngleAxisf(degrees * 3.14159265f / 180.f,
                                            Eigen::Vector3f::UnitZ());
  const TransformList skinning =
      skinningTransforms(rig.skeleton, globalTransforms(rig.skeleton, locals));
  CpuSkinning skinner(rig.mesh, rig.weights, rig.skeleton.jointCount());
  skinner.run(method, skinning, false);
  return skinner.positions();
}

TEST(SelfIntersection, LinearBlendFoldsABentCylinderThroughItself) {
  const Rig rig = makeCylinderRig();
  EXPECT_EQ(countSelfIntersections(rig.mesh.positions, rig.mesh.triangles), 0);
  // A slight bend stays clean; 135 degrees folds the inside of the joint.
  EXPECT_EQ(countSelfIntersections(
                bentCylinder(rig, SkinningMethod::kLinearBlend, 20.f),
                rig.mesh.triangles),
            0);
  const int folded = countSelfIntersections(
      bentCylinder(rig, SkinningMethod::kLinearBlend, 135.f),
      rig.mesh.triangles);
  EXPECT_GT(folded, 0);
}

// The message of the isk::Error that `call` throws (fails if none).
template <typename Call>
std::string invalidArgumentMessage(Call call) {
  try {
    call();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no isk::Error thrown";
  return "";
}

TEST(SelfIntersection, RejectsBadInput) {
  Matrix3Xf positions =
      positionsOf({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
  TriangleMatrix triangles = trianglesOf({{0, 1, 2}, {0, 2, 3}});
  for (float bad : {std::numeric_limits<float>::quiet_NaN(),
                    std::numeric_limits<float>::infinity()}) {
    Matrix3Xf broken = positions;
    broken(2, 1) = bad;
    const std::string message = invalidArgumentMessage(
        [&] { countSelfIntersections(broken, triangles); });
    EXPECT_NE(message.find("vertex 2"), std::string::npos) << message;
  }
  TriangleMatrix out_of_range = triangles;
  out_of_range(1, 2) = 4;
  std::string message = invalidArgumentMessage(
      [&] { countSelfIntersections(positions, out_of_range); });
  EXPECT_NE(message.find("triangle 1"), std::string::npos) << message;
  out_of_range(1, 2) = -1;
  message = invalidArgumentMessage(
      [&] { countSelfIntersections(positions, out_of_range); });
  EXPECT_NE(message.find("triangle 1"), std::string::npos) << message;
  const std::vector<int> short_groups = {0, 1, 2};
  message = invalidArgumentMessage(
      [&] { countSelfIntersections(positions, triangles, &short_groups); });
  EXPECT_NE(message.find("3 entries for 4 vertices"), std::string::npos)
      << message;
  // A group id must be a vertex index (the representative).
  for (int bad : {-1, 4}) {
    const std::vector<int> bad_groups = {0, 1, bad, 3};
    message = invalidArgumentMessage(
        [&] { countSelfIntersections(positions, triangles, &bad_groups); });
    EXPECT_NE(message.find("vertex 2 the group " + std::to_string(bad)),
              std::string::npos)
        << message;
  }
}

}  // namespace
}  // namespace isk
