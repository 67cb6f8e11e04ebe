// Measurements of deformed meshes used by reports and tests.
#pragma once

#include "isk/core/types.hpp"

namespace isk {

// Enclosed volume of `positions` (#V by 3) and `triangles` (#F by 3), in
// cubed model units, by the divergence theorem (exact for closed meshes,
// orientation-dependent sign; only ratios between frames of one mesh are
// meaningful for open meshes). Accumulated in double.
double enclosedVolume(const Matrix3Xf& positions,
                      const TriangleMatrix& triangles);

// Volume of the points that `positions` (#V by 3) and `triangles` (#F by 3)
// enclose, whatever their orientation and however many times: the points
// of non-zero winding number. Where skin passes through skin, the overlap
// counts once (enclosedVolume counts it twice, so interpenetration raises
// it), and a part wound inside out counts as solid. Measured along rays
// parallel to z through the centres of a `columns` by `columns` grid over
// the bounding box's xy extent: exact along each ray (its signed crossings
// in depth order), the grid's resolution across. For closed meshes; 0 for
// no triangle. Throws isk::Error(kInvalidArgument) for an index out of
// range or columns < 1.
double coveredVolume(const Matrix3Xf& positions,
                     const TriangleMatrix& triangles, int columns = 384);

// Diagonal of the axis-aligned bounding box; 0 for no vertex.
float boundingBoxDiagonal(const Matrix3Xf& positions);

// Largest distance between matching rows of a and b (#V by 3 each; 0 for no
// row; NaN when a row holds NaN). Throws isk::Error(kInvalidArgument) when
// the row counts differ.
float maxVertexDistance(const Matrix3Xf& a, const Matrix3Xf& b);

}  // namespace isk
