#include "isk/tools/mesh_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "isk/core/error.hpp"

namespace isk {

double enclosedVolume(const Matrix3Xf& positions,
                      const TriangleMatrix& triangles) {
  const Eigen::Index vertex_count = positions.rows();
  double six_volume = 0.0;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    Eigen::Vector3d corners[3];
    for (int c = 0; c < 3; ++c) {
      const int32_t index = triangles(f, c);
      if (index < 0 || index >= vertex_count) {
        throw Error(ErrorCode::kInvalidArgument,
                    "enclosedVolume: triangle " + std::to_string(f) +
                        " refers to vertex " + std::to_string(index) + " of " +
                        std::to_string(vertex_count));
      }
      corners[c] = positions.row(index).transpose().cast<double>();
    }
    // Signed volume of the tetrahedron (origin, a, b, c), times 6.
    six_volume += corners[0].dot(corners[1].cross(corners[2]));
  }
  return six_volume / 6.0;
}

float boundingBoxDiagonal(const Matrix3Xf& positions) {
  if (positions.rows() == 0) return 0.f;
  const Eigen::RowVector3f lo = positions.colwise().minCoeff();
  const Eigen::RowVector3f hi = positions.colwise().maxCoeff();
  return (hi - lo).norm();
}

float maxVertexDistance(const Matrix3Xf& a, const Matrix3Xf& b) {
  if (a.rows() != b.rows()) {
    throw Error(ErrorCode::kInvalidArgument,
                "maxVertexDistance: " + std::to_string(a.rows()) + " rows vs " +
                    std::to_string(b.rows()));
  }
  // An explicit loop so that a NaN row makes the result NaN (maxCoeff would
  // skip or keep it depending on where it falls).
  float result = 0.f;
  for (Eigen::Index v = 0; v < a.rows(); ++v) {
    const float d = (a.row(v) - b.row(v)).norm();
    if (std::isnan(d)) return d;
    result = std::max(result, d);
  }
  return result;
}

}  // namespace isk
