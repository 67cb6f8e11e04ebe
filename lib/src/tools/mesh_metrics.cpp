#include "isk/tools/mesh_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

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

double coveredVolume(const Matrix3Xf& positions,
                     const TriangleMatrix& triangles, int columns) {
  if (columns < 1)
    throw Error(ErrorCode::kInvalidArgument,
                "coveredVolume: " + std::to_string(columns) + " columns");
  const Eigen::Index vertex_count = positions.rows();
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int c = 0; c < 3; ++c)
      if (triangles(f, c) < 0 || triangles(f, c) >= vertex_count)
        throw Error(ErrorCode::kInvalidArgument,
                    "coveredVolume: triangle " + std::to_string(f) +
                        " refers to vertex " + std::to_string(triangles(f, c)) +
                        " of " + std::to_string(vertex_count));
  if (triangles.rows() == 0) return 0.0;
  const Eigen::Vector3d lo = positions.colwise().minCoeff().cast<double>();
  const Eigen::Vector3d hi = positions.colwise().maxCoeff().cast<double>();
  const double dx = (hi.x() - lo.x()) / columns;
  const double dy = (hi.y() - lo.y()) / columns;
  if (!(dx > 0) || !(dy > 0)) return 0.0;  // flat along x or y
  // Ray (i, j) passes through x = lo.x + (i + kX) dx, y likewise: offsets
  // off the cell centre so that rays rarely meet an edge of a regular mesh
  // exactly (one would count a crossing twice or not at all).
  constexpr double kX = 0.5 + 0.0137, kY = 0.5 - 0.0213;
  struct Crossing {
    double z;
    int step;  // +1 entering the surface upwards, -1 leaving it
  };
  // Two passes over the triangles: count each ray's crossings, then fill
  // them in, the rays' lists one after another.
  std::vector<uint32_t> offsets(static_cast<size_t>(columns) * columns + 1, 0);
  std::vector<Crossing> crossings;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<uint32_t> fill;
    if (pass == 1) {
      for (size_t r = 1; r < offsets.size(); ++r) offsets[r] += offsets[r - 1];
      crossings.resize(offsets.back());
      fill.assign(offsets.begin(), offsets.end() - 1);
    }
    for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
      Eigen::Vector3d p[3];
      for (int c = 0; c < 3; ++c)
        p[c] = positions.row(triangles(f, c)).transpose().cast<double>();
      const double area = (p[1].x() - p[0].x()) * (p[2].y() - p[0].y()) -
                          (p[1].y() - p[0].y()) * (p[2].x() - p[0].x());
      if (!(area != 0)) continue;  // seen edge-on by the rays (or NaN)
      const double x0 = std::min({p[0].x(), p[1].x(), p[2].x()});
      const double x1 = std::max({p[0].x(), p[1].x(), p[2].x()});
      const double y0 = std::min({p[0].y(), p[1].y(), p[2].y()});
      const double y1 = std::max({p[0].y(), p[1].y(), p[2].y()});
      const int i0 =
          std::max(0, static_cast<int>(std::ceil((x0 - lo.x()) / dx - kX)));
      const int i1 = std::min(
          columns - 1, static_cast<int>(std::floor((x1 - lo.x()) / dx - kX)));
      const int j0 =
          std::max(0, static_cast<int>(std::ceil((y0 - lo.y()) / dy - kY)));
      const int j1 = std::min(
          columns - 1, static_cast<int>(std::floor((y1 - lo.y()) / dy - kY)));
      // A surface wound outwards is entered upwards through the triangles
      // that face down (area < 0 seen from above).
      const int step = area < 0 ? 1 : -1;
      for (int j = j0; j <= j1; ++j) {
        const double y = lo.y() + (j + kY) * dy;
        for (int i = i0; i <= i1; ++i) {
          const double x = lo.x() + (i + kX) * dx;
          // Barycentric weights (times area) of the ray's point.
          double w[3];
          bool inside = true;
          for (int c = 0; c < 3 && inside; ++c) {
            const Eigen::Vector3d& a = p[(c + 1) % 3];
            const Eigen::Vector3d& b = p[(c + 2) % 3];
            w[c] =
                (b.x() - a.x()) * (y - a.y()) - (b.y() - a.y()) * (x - a.x());
            inside = area > 0 ? w[c] >= 0 : w[c] <= 0;
          }
          if (!inside) continue;
          const size_t ray = static_cast<size_t>(j) * columns + i;
          if (pass == 0) {
            ++offsets[ray + 1];
          } else {
            const double z =
                (w[0] * p[0].z() + w[1] * p[1].z() + w[2] * p[2].z()) / area;
            crossings[fill[ray]++] = {z, step};
          }
        }
      }
    }
  }
  double length = 0;  // summed over the rays
  for (size_t ray = 0; ray + 1 < offsets.size(); ++ray) {
    const auto begin = crossings.begin() + offsets[ray];
    const auto end = crossings.begin() + offsets[ray + 1];
    std::sort(begin, end,
              [](const Crossing& a, const Crossing& b) { return a.z < b.z; });
    int winding = 0;
    double below = 0;
    for (auto it = begin; it != end; ++it) {
      if (winding != 0) length += it->z - below;
      winding += it->step;
      below = it->z;
    }
  }
  return length * dx * dy;
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
