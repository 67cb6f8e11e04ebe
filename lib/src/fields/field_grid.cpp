#include "isk/fields/field_grid.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

#include "fields/trilinear.hpp"
#include "isk/core/error.hpp"

namespace isk {

Eigen::Vector4f FieldGrid::sampleLocal(const Eigen::Vector3f& local) const {
  const Eigen::Vector3f u = (local - box_min).cwiseQuotient(spacing());
  const float last = static_cast<float>(resolution - 1);
  if (!(u.x() >= 0 && u.y() >= 0 && u.z() >= 0 && u.x() <= last &&
        u.y() <= last && u.z() <= last))
    return Eigen::Vector4f::Zero();
  const float coordinates[3] = {u.x(), u.y(), u.z()};
  return detail::trilinearNodes(nodes.data(), resolution, coordinates);
}

std::vector<uint32_t> occupiedCells(const FieldGrid& grid) {
  const size_t n = static_cast<size_t>(std::max(grid.resolution, 2));
  const size_t cells = n - 1;
  std::vector<uint32_t> bits((cells * cells * cells + 31) / 32, 0u);
  if (grid.nodes.size() < 4 * n * n * n) return bits;
  // Nodes with any non-zero component, then each cell from its 8 corners.
  std::vector<uint8_t> live(n * n * n);
  for (size_t i = 0; i < live.size(); ++i) {
    const float* node = &grid.nodes[4 * i];
    live[i] =
        node[0] != 0.f || node[1] != 0.f || node[2] != 0.f || node[3] != 0.f;
  }
  for (size_t k = 0; k < cells; ++k)
    for (size_t j = 0; j < cells; ++j)
      for (size_t i = 0; i < cells; ++i) {
        bool any = false;
        for (size_t c = 0; c < 8 && !any; ++c)
          any = live[(i + (c & 1)) +
                     n * ((j + ((c >> 1) & 1)) + n * (k + (c >> 2)))] != 0;
        if (!any) continue;
        const size_t cell = i + cells * (j + cells * k);
        bits[cell / 32] |= 1u << (cell % 32);
      }
  return bits;
}

Eigen::AlignedBox3f occupiedBox(const FieldGrid& grid) {
  const int cells = std::max(grid.resolution, 2) - 1;
  const std::vector<uint32_t> occupied = occupiedCells(grid);
  Eigen::AlignedBox3i set;  // cell indices
  for (int k = 0; k < cells; ++k)
    for (int j = 0; j < cells; ++j)
      for (int i = 0; i < cells; ++i) {
        const size_t cell = static_cast<size_t>(i + cells * (j + cells * k));
        if ((occupied[cell / 32] >> (cell % 32)) & 1u)
          set.extend(Eigen::Vector3i(i, j, k));
      }
  Eigen::AlignedBox3f box;  // empty
  if (set.isEmpty()) return box;
  const Eigen::Vector3f spacing = grid.spacing();
  box.extend(grid.box_min + spacing.cwiseProduct(set.min().cast<float>()));
  box.extend(grid.box_min +
             spacing.cwiseProduct(
                 (set.max() + Eigen::Vector3i::Ones()).cast<float>()));
  return box;
}

std::vector<uint8_t> cellValueBounds(const FieldGrid& grid) {
  const size_t n = static_cast<size_t>(std::max(grid.resolution, 2));
  const size_t cells = n - 1;
  std::vector<uint8_t> bounds(cells * cells * cells, 0);
  if (grid.nodes.size() < 4 * n * n * n) return bounds;
  const std::vector<uint32_t> occupied = occupiedCells(grid);
  for (size_t k = 0; k < cells; ++k)
    for (size_t j = 0; j < cells; ++j)
      for (size_t i = 0; i < cells; ++i) {
        const size_t cell = i + cells * (j + cells * k);
        if (!((occupied[cell / 32] >> (cell % 32)) & 1u)) continue;
        float largest = 0.f;
        for (size_t c = 0; c < 8; ++c)
          largest = std::max(
              largest,
              grid.nodes[4 * ((i + (c & 1)) + n * ((j + ((c >> 1) & 1)) +
                                                   n * (k + (c >> 2))))]);
        // Not a number, or past the byte: no bound.
        const double b = std::floor(255.0 * largest) + 2.0;
        bounds[cell] = b >= 2.0 && b < 255.0 ? static_cast<uint8_t>(b) : 255;
      }
  return bounds;
}

FieldGrid bakeField(const BoneField& field, int resolution) {
  if (resolution < 2)
    throw Error(ErrorCode::kInvalidArgument,
                "bakeField: a grid needs at least 2 nodes per axis, got " +
                    std::to_string(resolution));
  FieldGrid grid;
  grid.joint = field.joint;
  grid.resolution = resolution;
  grid.bone_to_model = field.bone_to_model.cast<float>();
  grid.box_min = field.support_box.min().cast<float>();
  grid.box_max = field.support_box.max().cast<float>();
  const size_t n = static_cast<size_t>(resolution);
  grid.nodes.assign(4 * n * n * n, 0.f);

  // Evaluate in the HRBF's normalised frame, straight from its coefficients,
  // laid out as plain arrays so that the loop over centres vectorizes.
  const Hrbf& h = field.hrbf;
  const int m = h.centreCount();
  std::vector<double> cx(m), cy(m), cz(m), lambda(m), bx(m), by(m), bz(m);
  for (int q = 0; q < m; ++q) {
    cx[q] = h.normalisedCentres()[q].x();
    cy[q] = h.normalisedCentres()[q].y();
    cz[q] = h.normalisedCentres()[q].z();
    lambda[q] = h.lambdas()[q];
    bx[q] = h.betas()[q].x();
    by[q] = h.betas()[q].y();
    bz[q] = h.betas()[q].z();
  }
  const Eigen::Matrix3d rotation = field.bone_to_model.linear();
  const Eigen::Vector3d box_min = field.support_box.min();
  const Eigen::Vector3d step =
      field.support_box.sizes() / static_cast<double>(resolution - 1);
  const double scale = h.scale();
  const double bone_length = field.segment.length();
  for (size_t k = 0; k < n; ++k) {
    for (size_t j = 0; j < n; ++j) {
      for (size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d local =
            box_min + Eigen::Vector3d(i * step.x(), j * step.y(), k * step.z());
        // Beyond R + r from the bone the guard makes f = 0 and grad f = 0:
        // no need for the HRBF there (the box's corners and edges).
        const Eigen::Vector3d from_bone(
            local.x() - std::clamp(local.x(), 0.0, bone_length), local.y(),
            local.z());
        if (from_bone.norm() - field.guard_radius >= field.radius) continue;
        const Eigen::Vector3d x = field.bone_to_model * local;
        const Eigen::Vector3d u = (x - h.origin()) / scale;
        double d = h.linear().dot(u) + h.constant();
        double gx = h.linear().x(), gy = h.linear().y(), gz = h.linear().z();
        for (int q = 0; q < m; ++q) {
          const double vx = u.x() - cx[q], vy = u.y() - cy[q],
                       vz = u.z() - cz[q];
          const double r = std::sqrt(vx * vx + vy * vy + vz * vz);
          const double vb = vx * bx[q] + vy * by[q] + vz * bz[q];
          // lambda phi + beta . grad phi, and lambda grad phi + H beta; at
          // r = 0 the last term is 0/0 -> 0 (vb is 0 there too).
          const double w = 3.0 * vb / std::max(r, 1e-300);
          d += r * (lambda[q] * r * r + 3.0 * vb);
          gx += 3.0 * r * (lambda[q] * vx + bx[q]) + w * vx;
          gy += 3.0 * r * (lambda[q] * vy + by[q]) + w * vy;
          gz += 3.0 * r * (lambda[q] * vz + bz[q]) + w * vz;
        }
        d *= scale;
        Eigen::Vector3d g(gx, gy, gz);
        field.guard(x, d, g);
        const double f = reparameterize(d, field.radius);
        const Eigen::Vector3d grad = reparameterizeDerivative(d, field.radius) *
                                     (rotation.transpose() * g);
        float* out = &grid.nodes[4 * (i + n * (j + n * k))];
        out[0] = static_cast<float>(f);
        out[1] = static_cast<float>(grad.x());
        out[2] = static_cast<float>(grad.y());
        out[3] = static_cast<float>(grad.z());
      }
    }
  }
  return grid;
}

const char* gridPrecisionName(GridPrecision precision) {
  switch (precision) {
    case GridPrecision::kFloat:
      return "float";
    case GridPrecision::kHalf:
      return "half";
  }
  return "unknown";
}

void roundGridsToHalf(FieldGridSet& grids) {
  // Checked first, so that a refused set is left as it was.
  for (const FieldGrid& g : grids.grids) {
    for (size_t i = 0; i < g.nodes.size(); ++i) {
      const float x = g.nodes[i];
      if (std::isfinite(x) &&
          !std::isfinite(static_cast<float>(Eigen::half(x)))) {
        const size_t node = i / 4;
        const size_t n = static_cast<size_t>(std::max(g.resolution, 1));
        throw Error(
            ErrorCode::kInvalidArgument,
            "roundGridsToHalf: the field of joint " + std::to_string(g.joint) +
                " has " +
                (i % 4 == 0 ? std::string("value ") : "gradient component ") +
                std::to_string(x) + " at node (" + std::to_string(node % n) +
                ", " + std::to_string(node / n % n) + ", " +
                std::to_string(node / (n * n)) +
                "), beyond half precision's range (65504): the "
                "model's units are too small for half-precision "
                "grids; keep them in float");
      }
    }
  }
  for (FieldGrid& g : grids.grids)
    for (float& x : g.nodes) x = static_cast<float>(Eigen::half(x));
  grids.precision = GridPrecision::kHalf;
}

size_t FieldGridSet::bytes() const {
  size_t total = 0;
  for (const auto& g : grids) total += g.bytes();
  return total;
}

}  // namespace isk
