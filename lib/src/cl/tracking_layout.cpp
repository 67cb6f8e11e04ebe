#include "cl/tracking_layout.hpp"

#include <algorithm>

#include "abi.h"
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
  out->rest_creases = permuted(mesh.rest_crease, order);
  out->home_margins = permuted(mesh.home_margin, order);
  out->home_floors.resize(2 * static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) {
    out->home_floors[2 * k] = homeFloor(mesh, order[k], options);
    out->home_floors[2 * k + 1] = homeMinimum(mesh, order[k], options);
  }
  const TrackingLengths lengths = trackingLengths(mesh, options);
  out->step_limits.resize(2 * static_cast<size_t>(n));
  out->smoothing_radii.resize(n);
  out->bulge_reaches.resize(n);
  for (int k = 0; k < n; ++k) {
    out->bulge_reaches[k] = lengths.bulge_reach[order[k]];
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
  out->near_mean_lengths.assign(n, 0.f);
  for (int k = 0; k < n; ++k) {
    float length = 0.f;
    int near = 0;
    for (uint32_t i = out->ring_offsets[k]; i < out->ring_offsets[k + 1]; ++i)
      if (lengths[i] <= out->smoothing_radii[k]) {
        out->near_neighbours.push_back(out->ring_neighbours[i]);
        length += lengths[i];
        ++near;
      }
    if (near > 0) out->near_mean_lengths[k] = length / static_cast<float>(near);
    out->near_offsets.push_back(
        static_cast<uint32_t>(out->near_neighbours.size()));
  }
}

// The transpose of compressed rows over n vertices: per vertex the
// vertices whose rows list it, in ascending order.
void transposeRows(int n, const std::vector<uint32_t>& offsets,
                   const std::vector<int>& neighbours,
                   std::vector<uint32_t>* out_offsets,
                   std::vector<int>* out_neighbours) {
  out_offsets->assign(n + 1, 0);
  for (int w : neighbours) ++(*out_offsets)[w + 1];
  for (int k = 0; k < n; ++k) (*out_offsets)[k + 1] += (*out_offsets)[k];
  out_neighbours->resize(neighbours.size());
  std::vector<uint32_t> fill(out_offsets->begin(), out_offsets->end() - 1);
  for (int k = 0; k < n; ++k)
    for (uint32_t i = offsets[k]; i < offsets[k + 1]; ++i)
      (*out_neighbours)[fill[neighbours[i]]++] = k;
}

void reverseRows(TrackingDeviceLayout* out) {
  const int n = static_cast<int>(out->order.size());
  transposeRows(n, out->near_offsets, out->near_neighbours,
                &out->reverse_offsets, &out->reverse_neighbours);
  transposeRows(n, out->ring_offsets, out->ring_neighbours,
                &out->ring_reverse_offsets, &out->ring_reverse_neighbours);
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

// Chunks of at most ISK_VOLUME_CHUNK items of each group, whose items
// are [offsets[g], offsets[g + 1]).
void volumeChunks(const std::vector<int>& offsets, std::vector<int>* chunks,
                  std::vector<int>* chunk_offsets) {
  chunk_offsets->assign(1, 0);
  for (size_t g = 0; g + 1 < offsets.size(); ++g) {
    for (int first = offsets[g]; first < offsets[g + 1];
         first += ISK_VOLUME_CHUNK)
      chunks->insert(chunks->end(),
                     {static_cast<int>(g), first,
                      std::min(first + ISK_VOLUME_CHUNK, offsets[g + 1]), 0});
    chunk_offsets->push_back(static_cast<int>(chunks->size() / 4));
  }
}

void volumeRows(const TrackingMesh& mesh, TrackingDeviceLayout* out) {
  const TrackingMesh::VolumeGroups& groups = mesh.volume_groups;
  const int n = static_cast<int>(out->order.size());
  for (const int v : groups.corners)
    out->volume_corners.push_back(out->slot_of[v]);
  for (int g = 0; g < groups.groupCount(); ++g) {
    out->volume_origins.push_back(
        out->volume_corners[3 *
                            static_cast<size_t>(groups.triangle_offsets[g])]);
    out->volume_rest.push_back(static_cast<float>(groups.rest_volume[g]));
  }
  volumeChunks(groups.triangle_offsets, &out->volume_triangle_chunks,
               &out->volume_triangle_chunk_offsets);
  out->volume_groups.assign(n, -1);
  out->volume_areas.assign(n, 0.f);
  out->volume_signs.assign(n, 1.f);
  out->volume_near.assign(n, 0);
  if (static_cast<int>(groups.near_other.size()) == n)
    for (int k = 0; k < n; ++k)
      out->volume_near[k] = groups.near_other[out->order[k]];
  std::vector<int> vertex_offsets(groups.groupCount() + 1, 0);
  for (int k = 0; k < n; ++k) {
    const int v = out->order[k];
    const int g = static_cast<int>(groups.vertex_group.size()) == n &&
                          static_cast<int>(groups.normal_sign.size()) == n
                      ? groups.vertex_group[v]
                      : -1;
    out->volume_groups[k] = g;
    out->volume_areas[k] = g < 0 ? 0.f : groups.vertex_area[v];
    out->volume_signs[k] = g < 0 ? 1.f : groups.normal_sign[v];
    if (g >= 0) ++vertex_offsets[g + 1];
  }
  for (int g = 0; g < groups.groupCount(); ++g)
    vertex_offsets[g + 1] += vertex_offsets[g];
  // In the mesh's order, so that the sums do not depend on the march order.
  out->volume_vertices.resize(vertex_offsets.back());
  std::vector<int> fill(vertex_offsets.begin(), vertex_offsets.end() - 1);
  for (int v = 0; v < n; ++v) {
    const int k = out->slot_of[v];
    if (out->volume_groups[k] >= 0)
      out->volume_vertices[fill[out->volume_groups[k]]++] = k;
  }
  volumeChunks(vertex_offsets, &out->volume_vertex_chunks,
               &out->volume_vertex_chunk_offsets);
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
  volumeRows(mesh, &out);
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
