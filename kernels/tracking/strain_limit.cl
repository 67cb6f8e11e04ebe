// Surface tracking, the strain limit (our addition, docs/algorithm.md): each
// tracked vertex's offset from its skinned position, d = x - s, is pulled
// towards its neighbours' where two ends of a ring edge differ by more than
// strain_limit times the edge's rest length, so that an edge's length stays
// within about that fraction of its skinned length. OpenCL C 1.2. CPU
// reference: CpuSurfaceTracking::limitStrain
// (lib/src/tracking/surface_tracking.cpp).
//
// Per-vertex arrays and the one-rings are in the device's vertex order
// (tracking/project.cl); the skinned positions are in the mesh's order,
// device index k reading skinned[source[k]]. The steps work on the offsets
// (packed float triples, ping-pong). The first step visits every tracked
// vertex; each later one only its active vertices (a uchar per vertex,
// ping-pong): those whose ring or self the last step or a fold check moved.
// A vertex none of whose ring moved has the same edges as in the last step,
// none violated, and is left as it is: its offset is the same in both
// buffers (both start equal, and a step that does not move a vertex it
// visits copies its offset across). Visiting a vertex that is not active
// changes nothing.

#include "common.h"

// The offsets from the skinned positions, in both buffers.
__kernel void track_strain_offsets(const uint vertex_count,
                                   __global const float* positions,
                                   __global const float* skinned,
                                   __global const int* source,
                                   __global float* offsets,
                                   __global float* offsets_other) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const float3 d = vload3(v, positions) - vload3(source[v], skinned);
  vstore3(d, v, offsets);
  vstore3(d, v, offsets_other);
}

// One Jacobi step for one vertex (strainLimitStep): its offset d moved, for
// each ring edge whose offsets differ by more than its limit * rest length,
// by half the excess towards the neighbour's offset, over the ring's size
// (continuous as an edge starts to violate). An edge's limit goes from limit
// to fold_limit by the larger fold weight of its ends (the fold guard,
// tracking/fold_guard.cl). Only the tracked vertices (the first
// march_count, march order) move: with `all` every one, else those marked in
// active_in (the mark cleared). A vertex that moves marks itself and the
// vertices whose rings list it (the rings' transpose) in active_out, and its
// triangles (fold rows) for the fold guard's next check.
__kernel void track_limit_strain(
    const uint march_count, const int all, __global uchar* active_in,
    __global uchar* active_out, __global const float* offsets_in,
    __global float* offsets_out, __global const uint* ring_offsets,
    __global const int* ring_neighbours, __global const float* ring_lengths,
    const float limit, __global const float* fold_weights,
    const float fold_limit, __global const uint* reverse_offsets,
    __global const int* reverse_neighbours, __global const uint* fold_offsets,
    __global const int* fold_triangles, __global uchar* dirty_triangles) {
  const uint v = get_global_id(0);
  if (v >= march_count) return;
  if (!all && !active_in[v]) return;
  active_in[v] = 0;
  const uint begin = ring_offsets[v], end = ring_offsets[v + 1];
  const float3 d = vload3(v, offsets_in);
  float3 out = d;
  float3 correction = (float3)(0.0f);
  bool violated = false;
  const float fold_v = fold_weights[v];
  for (uint i = begin; i < end; ++i) {
    const int u = ring_neighbours[i];
    const float3 diff = d - vload3(u, offsets_in);
    const float length =
        sqrt(diff.x * diff.x + diff.y * diff.y + diff.z * diff.z);
    const float w = fmax(fold_v, fold_weights[u]);
    const float edge_limit = limit + w * (fold_limit - limit);
    const float excess = length - edge_limit * ring_lengths[i];
    if (excess > 0.0f) {
      correction -= (0.5f * excess / length) * diff;
      violated = true;
    }
  }
  if (violated) {
    out = d + correction / (float)(end - begin);
    active_out[v] = 1;
    for (uint i = reverse_offsets[v]; i < reverse_offsets[v + 1]; ++i) {
      const int w = reverse_neighbours[i];
      if ((uint)w < march_count) active_out[w] = 1;
    }
    for (uint i = fold_offsets[v]; i < fold_offsets[v + 1]; ++i)
      dirty_triangles[fold_triangles[i]] = 1;
  }
  vstore3(out, v, offsets_out);
}

// Back to positions: s + d where the steps changed the offset, the position
// itself where they did not (bit for bit).
__kernel void track_strain_positions(const uint vertex_count,
                                     __global float* positions,
                                     __global const float* skinned,
                                     __global const int* source,
                                     __global const float* offsets) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const float3 x = vload3(v, positions);
  const float3 s = vload3(source[v], skinned);
  const float3 d0 = x - s;
  const float3 d = vload3(v, offsets);
  if (d.x != d0.x || d.y != d0.y || d.z != d0.z) vstore3(s + d, v, positions);
}
