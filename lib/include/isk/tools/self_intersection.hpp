// Self-intersections of a triangle mesh, the per-frame measure of skinning
// quality: a skin that folds through itself (linear blend skinning inside a
// bent joint, or a spike where adjacent triangles fold over each other) has
// pairs of intersecting triangles; a skin that resolves contact has none.
//
// What is counted is exactly what CGAL counts:
// CGAL::Polygon_mesh_processing::self_intersections (CGAL 5.5,
// Polygon_mesh_processing/self_intersections.h, do_faces_intersect and the
// degenerate-face test of its box loop) on the mesh welded by vertex group.
// Every pair of triangles is judged, adjacent ones included, by how many
// welded vertices the two share:
//   - none: the closed triangles intersect (touching counts);
//   - one: the edge of either triangle opposite the shared vertex meets the
//     other closed triangle (a neighbour around a vertex folded through);
//   - two (an edge): the four points are coplanar and the two opposite
//     vertices lie on the same side of the shared edge (folded flat onto
//     each other); a sharp fold that is not exactly flat does not count;
//   - three (a doubled face): always.
// Degenerate triangles (collinear corners after welding, exactly) are left
// out of every pair; CGAL reports each as a pair (f, f), here they are
// counted apart.
//
// Candidate pairs come from a bounding-volume hierarchy over the triangles'
// boxes traversed against itself. Each candidate then goes through exact
// tests that, like Guigue and Devillers 2003 ("Fast and Robust
// Triangle-Triangle Overlap Test Using Orientation Predicates"), only take
// signs of orientation determinants and never construct intersection points.
// The determinants are evaluated in double behind an error bound and exactly
// (floating-point expansions: Shewchuk 1997, "Adaptive Precision
// Floating-Point Arithmetic and Fast Robust Geometric Predicates") when the
// bound cannot decide, so results are exact for the float positions given,
// coplanar and touching configurations included.
//
// Triangles are closed sets: triangles that only touch intersect. Seam
// duplicates (same position, different index) therefore count unless they
// are welded through vertex groups; an exact touch between non-adjacent
// triangles does not happen by chance in a skinned frame.
#pragma once

#include <utility>
#include <vector>

#include "isk/core/types.hpp"

namespace isk {

// Pairs (a, b), a < b, of triangles that intersect as CGAL defines it (see
// above: adjacent fold-overs included); returns their number and, when
// `pairs` is given, fills it with them sorted by (a, b). `positions` is #V
// by 3, `triangles` #F by 3.
// `vertex_groups` (optional, #V) welds vertices: each entry is a vertex
// index, the group's representative, and every corner referring to a vertex
// of the group is that representative, at the representative's position
// (duplicates along UV seams of imported meshes: triangles on either side of
// a seam then share the seam's vertices). nullptr: each vertex is its own.
// `degenerate_triangles` (optional) receives the number of triangles left
// out as degenerate (collinear corners after welding).
// Throws isk::Error(kInvalidArgument) naming the vertex or triangle for
// non-finite positions (of any vertex, referenced or not), out-of-range
// indices, or a vertex_groups of the wrong size or with an entry that is not
// a vertex index.
int countSelfIntersections(const Matrix3Xf& positions,
                           const TriangleMatrix& triangles,
                           const std::vector<int>* vertex_groups = nullptr,
                           std::vector<std::pair<int, int>>* pairs = nullptr,
                           int* degenerate_triangles = nullptr);

// The pairs of `frame_pairs` that are not in `rest_pairs` (in any order;
// countSelfIntersections gives them sorted), sorted and without repeats: the
// intersections a deformation introduced. A report counts these, because some
// assets already intersect at rest.
std::vector<std::pair<int, int>> newSelfIntersections(
    const std::vector<std::pair<int, int>>& frame_pairs,
    const std::vector<std::pair<int, int>>& rest_pairs);

// Group id per vertex for countSelfIntersections: vertices at exactly the
// same position (bitwise-equal floats, so 0 and -0 differ) share the smallest
// index among them. #V entries.
std::vector<int> coincidentVertexGroups(const Matrix3Xf& positions);

}  // namespace isk
