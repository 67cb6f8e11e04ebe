// The tracking mesh laid out for the device: everything ClSurfaceTracking
// uploads once per character, computed on the host with no device, so that
// it can be tested on its own.
//
// The device keeps the vertices in their march order (the tracked vertices
// first, in TrackingMesh::march_order, then the others by index): the
// projection reads and writes its per-vertex data in sequence, and march
// slot k is vertex k on the device. Every per-vertex array below is in that
// order (#V entries, index k: the mesh vertex order[k]); ring entries are
// device indices.
#pragma once

#include <cstdint>
#include <vector>

#include "isk/tracking/surface_tracking.hpp"

namespace isk::detail {

struct TrackingDeviceLayout {
  std::vector<int> order;    // #V: the mesh vertex at device index k
  std::vector<int> slot_of;  // #V: the device index of mesh vertex v
  int march_count = 0;       // the tracked vertices, order's first entries
  // Seam copies: the device index of each vertex's representative, by
  // device index (representative) and by mesh index (finish_source: where
  // finish() takes each mesh vertex's result from).
  std::vector<int> representative, finish_source;
  std::vector<float> iso_values, home_margins;
  std::vector<float> home_floors;  // #slots by 2: homeFloor, homeMinimum
  std::vector<int> home_fields;
  std::vector<int> rest_creases;      // TrackingMesh::rest_crease, by slot
  std::vector<uint8_t> rules, kinds;  // RelaxationRule, RingKind
  std::vector<float> step_limits;     // 2 per vertex: max step, min gradient
  std::vector<float> smoothing_radii;
  std::vector<float> bulge_reaches;  // trackingLengths' bulge_reach
  // The one-rings as compressed rows, #V + 1 offsets.
  std::vector<uint32_t> ring_offsets;
  std::vector<int> ring_neighbours;
  std::vector<float> ring_weights;
  std::vector<float> ring_lengths;  // rest lengths (the strain limit)
  // The rows filtered to the neighbours within each vertex's smoothing
  // radius (rest distance), in ring order: the rows the diffusion and the
  // Laplacian steps average over.
  std::vector<uint32_t> near_offsets;
  std::vector<int> near_neighbours;
  // Per device index the mean rest length of its near neighbours (summed in
  // ring order, as CpuSurfaceTracking::smooth does), 0 where it has none:
  // the crease gate's unit.
  std::vector<float> near_mean_lengths;
  // Their transpose: the vertices whose near rows list each vertex, where a
  // contact or crease vertex pushes its reach (active vertices).
  std::vector<uint32_t> reverse_offsets;
  std::vector<int> reverse_neighbours;
  // The rings' transpose: per device index the vertices whose rings list
  // it (where the strain limit's steps and fold checks mark what a change
  // reaches).
  std::vector<uint32_t> ring_reverse_offsets;
  std::vector<int> ring_reverse_neighbours;
  // The fold guard: each triangle's corners as the device indices of their
  // representatives (#F by 3), and per device index the triangles with a
  // corner in its welded group (compressed rows, #V + 1 offsets; empty for
  // seam copies).
  std::vector<int> fold_corners;
  std::vector<uint32_t> fold_offsets;
  std::vector<int> fold_triangles;
  // Volume restoration (TrackingMesh::VolumeGroups) in device indices: the
  // groups' triangles (3 corners each, group by group), each group's first
  // corner, its rest volume; its vertices (device indices, group by group);
  // the sums' chunks (4 ints each: group, first, end, 0; at most
  // ISK_VOLUME_CHUNK triangles or vertices of one group) and each group's
  // first chunk (#groups + 1); per device index its group (-1), area and
  // normal sign.
  std::vector<int> volume_corners, volume_origins;
  std::vector<float> volume_rest;
  std::vector<int> volume_vertices;
  std::vector<int> volume_triangle_chunks, volume_triangle_chunk_offsets;
  std::vector<int> volume_vertex_chunks, volume_vertex_chunk_offsets;
  std::vector<int> volume_groups;
  std::vector<float> volume_areas, volume_signs;
  std::vector<uint8_t> volume_near;  // VolumeGroups::near_other
};

// The tuning's march_order off keeps the tracked vertices by index instead
// of TrackingMesh::march_order (tracking/tracking_tuning.hpp).
TrackingDeviceLayout trackingDeviceLayout(
    const TrackingMesh& mesh, const SurfaceTrackingOptions& options);

// Cells per axis of the neighbourhoods' split for a device: the tuning's when
// set; else on a CPU device `cpu_cells` for a character with 100 tracked
// vertices per field or more, since the split's host time and upload grow
// with the fields and its gain with the vertices (docs/performance.md);
// elsewhere 1, the whole box: a GPU's frame is bound by launches.
int neighbourhoodCellsPerAxis(const TrackingMesh& mesh,
                              const SurfaceTrackingOptions& options,
                              bool cpu_device, int cpu_cells);

}  // namespace isk::detail
