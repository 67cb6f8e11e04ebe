// Self-intersections of a triangle mesh, the per-frame measure of skinning
// quality: a skin that folds through itself (linear blend skinning inside a
// bent joint) has pairs of non-adjacent triangles that intersect, a skin that
// resolves contact (implicit skinning) has none.
//
// Candidate pairs come from a bounding-volume hierarchy over the triangles'
// boxes traversed against itself. Each candidate then goes through an exact
// triangle-triangle test that, like Guigue and Devillers 2003 ("Fast and
// Robust Triangle-Triangle Overlap Test Using Orientation Predicates"), only
// takes signs of orientation determinants and never constructs intersection
// points: two closed triangles meet iff an edge of one meets the other.
// The determinants are evaluated in double behind an error bound and exactly
// (floating-point expansions: Shewchuk 1997, "Adaptive Precision
// Floating-Point Arithmetic and Fast Robust Geometric Predicates") when the
// bound cannot decide, so results are exact for the float positions given,
// coplanar and touching configurations included.
//
// Triangles are closed sets: triangles that only touch (at a single point of
// an edge, along an edge, at a vertex) intersect. This makes seam duplicates
// count unless grouped, and it is the conservative choice for a quality
// measure; an exact touch between non-adjacent triangles does not happen by
// chance in a skinned frame.
#pragma once

#include <utility>
#include <vector>

#include "isk/core/types.hpp"

namespace isk {

// Pairs (a, b), a < b, of triangles that intersect and share no vertex;
// returns their number and, when `pairs` is given, fills it with them sorted
// by (a, b). `positions` is #V by 3, `triangles` #F by 3.
// `vertex_groups` (optional, #V): vertices with the same group id count as one
// vertex (duplicates along UV seams of imported meshes: triangles on either
// side of a seam touch along an edge but share no index). nullptr: each vertex
// is its own group.
// Degenerate (zero-area, exactly) triangles are ignored. Throws
// isk::Error(kInvalidArgument) naming the vertex or triangle for non-finite
// positions (of any vertex, referenced or not), out-of-range indices or a
// vertex_groups of the wrong size.
int countSelfIntersections(const Matrix3Xf& positions,
                           const TriangleMatrix& triangles,
                           const std::vector<int>* vertex_groups = nullptr,
                           std::vector<std::pair<int, int>>* pairs = nullptr);

// Group id per vertex for countSelfIntersections: vertices at exactly the
// same position (bitwise-equal floats, so 0 and -0 differ) share the smallest
// index among them. #V entries.
std::vector<int> coincidentVertexGroups(const Matrix3Xf& positions);

}  // namespace isk
