// Trilinear interpolation of a grid of float4 nodes, in the order of
// operations the kernels' buffer paths use (kernels/fields/sample.cl:
// trilinear_nodes), so that a CPU device agrees to the last bits. Shared by
// the baked fields (FieldGrid) and the operator tables (OperatorTable).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>

namespace isk::detail {

// `nodes`: resolution^3 float4, node (x, y, z) at x + N * (y + N * z);
// `u`: node coordinates, each in [0, N - 1].
inline Eigen::Vector4f trilinearNodes(const float* nodes, int resolution,
                                      const float u[3]) {
  int i[3];
  float t[3];
  for (int a = 0; a < 3; ++a) {
    i[a] = std::min(static_cast<int>(u[a]), resolution - 2);
    t[a] = u[a] - static_cast<float>(i[a]);
  }
  const size_t n = static_cast<size_t>(resolution);
  auto node = [&](int dx, int dy, int dz) {
    const size_t index = (i[0] + dx) + n * ((i[1] + dy) + n * (i[2] + dz));
    return Eigen::Map<const Eigen::Vector4f>(nodes + 4 * index);
  };
  const Eigen::Vector4f x00 =
      node(0, 0, 0) + t[0] * (node(1, 0, 0) - node(0, 0, 0));
  const Eigen::Vector4f x10 =
      node(0, 1, 0) + t[0] * (node(1, 1, 0) - node(0, 1, 0));
  const Eigen::Vector4f x01 =
      node(0, 0, 1) + t[0] * (node(1, 0, 1) - node(0, 0, 1));
  const Eigen::Vector4f x11 =
      node(0, 1, 1) + t[0] * (node(1, 1, 1) - node(0, 1, 1));
  const Eigen::Vector4f y0 = x00 + t[1] * (x10 - x00);
  const Eigen::Vector4f y1 = x01 + t[1] * (x11 - x01);
  return y0 + t[2] * (y1 - y0);
}

}  // namespace isk::detail
