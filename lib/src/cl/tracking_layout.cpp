#include "cl/tracking_layout.hpp"

#include <algorithm>

#include "tracking/tracking_tuning.hpp"

namespace isk::detail {
namespace {

// `by_vertex` (mesh order) in device order.
template <typename T>
std::vector<T> permuted(const std::vector<T>& by_vertex,
                        const std::vector<int>& order) {
  std::vector<T> out(by_vertex.size());
  for (size_t k = 0; k < order.size(); ++k) out[k] = by_vertex[order[k]];
  return out;
}

void deviceOrder(const TrackingMesh& mesh, bool march_order,
                 TrackingDeviceLayout* out) {
  const int n = mesh.vertexCount();
  out->order = mesh.march_order;
  if (!march_order) std::sort(out->order.begin(), out->order.end());
  out->march_count = static_cast<int>(out->order.size());
  out->slot_of.assign(n, -1);
  for (int k = 0; k < out->march_count; ++k) out->slot_of[out->order[k]] = k;
  for (int v = 0; v < n; ++v)
    if (out->slot_of[v] < 0) {
      out->slot_of[v] = static_cast<int>(out->order.size());
      out->order.push_back(v);
    }
}

void perVertexData(const TrackingMesh& mesh,
                   const SurfaceTrackingOptions& options,
                   TrackingDeviceLayout* out) {
  const int n = mesh.vertexCount();
  const std::vector<int>& order = out->order;
  out->iso_values = permuted(mesh.iso_values, order);
  out->representative.resize(n);
  out->finish_source.resize(n);
  for (int k = 0; k < n; ++k)
    out->representative[k] = out->slot_of[mesh.rings.representative[order[k]]];
  for (int v = 0; v < n; ++v)
    out->finish_source[v] = out->slot_of[mesh.rings.representative[v]];
  out->rules.resize(mesh.relaxation.rules.size());
  for (size_t k = 0; k < out->rules.size(); ++k)
    out->rules[k] = static_cast<uint8_t>(mesh.relaxation.rules[order[k]]);
  out->kinds.resize(mesh.rings.kinds.size());
  for (size_t k = 0; k < out->kinds.size(); ++k)
    out->kinds[k] = static_cast<uint8_t>(mesh.rings.kinds[order[k]]);
  out->home_fields = permuted(mesh.home_field, order);
  out->home_margins = permuted(mesh.home_margin, order);
  out->home_floors.resize(2 * static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) {
    out->home_floors[2 * k] = homeFloor(mesh, order[k], options);
    out->home_floors[2 * k + 1] = homeMinimum(mesh, order[k], options);
  }
  const TrackingLengths lengths = trackingLengths(mesh, options);
  out->step_limits.resize(2 * static_cast<size_t>(n));
  out->smoothing_radii.resize(n);
  for (int k = 0; k < n; ++k) {
    out->step_limits[2 * k] = lengths.max_step[order[k]];
    out->step_limits[2 * k + 1] = lengths.min_gradient[order[k]];
    out->smoothing_radii[k] = lengths.smoothing_radius[order[k]];
  }
}

// The rings in device order, their rest lengths in `lengths`.
void ringRows(const TrackingMesh& mesh, TrackingDeviceLayout* out,
              std::vector<float>* lengths) {
  out->ring_offsets.assign(1, 0);
  out->ring_neighbours.reserve(mesh.rings.neighbours.size());
  for (const int v : out->order) {
    for (uint32_t i = mesh.rings.offsets[v]; i < mesh.rings.offsets[v + 1];
         ++i) {
      out->ring_neighbours.push_back(out->slot_of[mesh.rings.neighbours[i]]);
      out->ring_weights.push_back(mesh.relaxation.weights[i]);
      lengths->push_back(mesh.ring_lengths[i]);
    }
    out->ring_offsets.push_back(
        static_cast<uint32_t>(out->ring_neighbours.size()));
  }
}

void nearRows(const std::vector<float>& lengths, TrackingDeviceLayout* out) {
  const int n = static_cast<int>(out->order.size());
  out->near_offsets.assign(1, 0);
  out->near_neighbours.reserve(out->ring_neighbours.size());
  for (int k = 0; k < n; ++k) {
    for (uint32_t i = out->ring_offsets[k]; i < out->ring_offsets[k + 1]; ++i)
      if (lengths[i] <= out->smoothing_radii[k])
        out->near_neighbours.push_back(out->ring_neighbours[i]);
    out->near_offsets.push_back(
        static_cast<uint32_t>(out->near_neighbours.size()));
  }
}

void reverseRows(TrackingDeviceLayout* out) {
  const int n = static_cast<int>(out->order.size());
  const std::vector<int>& near = out->near_neighbours;
  out->reverse_offsets.assign(n + 1, 0);
  for (int w : near) ++out->reverse_offsets[w + 1];
  for (int k = 0; k < n; ++k)
    out->reverse_offsets[k + 1] += out->reverse_offsets[k];
  out->reverse_neighbours.resize(near.size());
  std::vector<uint32_t> fill(out->reverse_offsets.begin(),
                             out->reverse_offsets.end() - 1);
  for (int k = 0; k < n; ++k)
    for (uint32_t i = out->near_offsets[k]; i < out->near_offsets[k + 1]; ++i)
      out->reverse_neighbours[fill[near[i]]++] = k;
}

void foldRows(const TrackingMesh& mesh, TrackingDeviceLayout* out) {
  const int n = static_cast<int>(out->order.size());
  const TriangleMatrix& triangles = mesh.triangles;
  out->fold_corners.resize(3 * static_cast<size_t>(triangles.rows()));
  out->fold_offsets.assign(n + 1, 0);
  for (Eigen::Index t = 0; t < triangles.rows(); ++t)
    for (int c = 0; c < 3; ++c) {
      const int k = out->slot_of[mesh.rings.representative[triangles(t, c)]];
      out->fold_corners[3 * t + c] = k;
      ++out->fold_offsets[k + 1];
    }
  for (int k = 0; k < n; ++k) out->fold_offsets[k + 1] += out->fold_offsets[k];
  out->fold_triangles.resize(out->fold_corners.size());
  std::vector<uint32_t> fill(out->fold_offsets.begin(),
                             out->fold_offsets.end() - 1);
  for (size_t i = 0; i < out->fold_corners.size(); ++i)
    out->fold_triangles[fill[out->fold_corners[i]]++] = static_cast<int>(i / 3);
}

}  // namespace

TrackingDeviceLayout trackingDeviceLayout(
    const TrackingMesh& mesh, const SurfaceTrackingOptions& options) {
  TrackingDeviceLayout out;
  deviceOrder(mesh, tuningOf(options).march_order, &out);
  perVertexData(mesh, options, &out);
  std::vector<float> lengths;
  ringRows(mesh, &out, &lengths);
  nearRows(lengths, &out);
  out.ring_lengths = std::move(lengths);
  reverseRows(&out);
  foldRows(mesh, &out);
  return out;
}

int neighbourhoodCellsPerAxis(const TrackingMesh& mesh,
                              const SurfaceTrackingOptions& options,
                              bool cpu_device, int cpu_cells) {
  const int cells = tuningOf(options).neighbourhood_cells;
  if (cells > 0) return cells;
  const bool many_vertices =
      mesh.march_order.size() >=
      100 * static_cast<size_t>(std::max(mesh.field_count, 1));
  return cpu_device && many_vertices ? cpu_cells : 1;
}

}  // namespace isk::detail
