// Array shapes shared by the whole library (libigl's style: shapes in names).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace isk {

// #V by 3 float rows (positions, normals), row-major so a mesh uploads as one
// contiguous float array (x0 y0 z0 x1 ...).
using Matrix3Xf = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;
// #F by 3 vertex indices of triangles, row-major.
using TriangleMatrix =
    Eigen::Matrix<int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;

// One rigid-or-affine transform per joint, model space.
using TransformList = std::vector<Eigen::Affine3f>;

}  // namespace isk
