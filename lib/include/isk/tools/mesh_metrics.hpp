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

// Diagonal of the axis-aligned bounding box; 0 for no vertex.
float boundingBoxDiagonal(const Matrix3Xf& positions);

// Largest distance between matching rows of a and b (#V by 3 each; 0 for no
// row; NaN when a row holds NaN). Throws isk::Error(kInvalidArgument) when
// the row counts differ.
float maxVertexDistance(const Matrix3Xf& a, const Matrix3Xf& b);

}  // namespace isk
