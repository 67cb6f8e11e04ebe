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
// device index k reading skinned[source[k]].

#include "common.h"

// One Jacobi step for one vertex: x (offset d) moved, for each ring edge
// whose offsets differ by more than limit * rest length, by half the excess
// towards the neighbour's offset, over the ring's size (continuous as an
// edge starts to violate).
__kernel void track_limit_strain(const uint vertex_count,
                                 const uint march_count,
                                 __global const float* positions_in,
                                 __global float* positions_out,
                                 __global const float* skinned,
                                 __global const int* source,
                                 __global const uint* ring_offsets,
                                 __global const int* ring_neighbours,
                                 __global const float* ring_lengths,
                                 const float limit) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const float3 x = vload3(v, positions_in);
  float3 out = x;
  // The tracked vertices are the first march_count (march order).
  if (v < march_count) {
    const float3 d = x - vload3(source[v], skinned);
    float3 correction = (float3)(0.0f);
    bool violated = false;
    const uint end = ring_offsets[v + 1];
    for (uint i = ring_offsets[v]; i < end; ++i) {
      const int u = ring_neighbours[i];
      const float3 diff =
          d - (vload3(u, positions_in) - vload3(source[u], skinned));
      const float length =
          sqrt(diff.x * diff.x + diff.y * diff.y + diff.z * diff.z);
      const float excess = length - limit * ring_lengths[i];
      if (excess > 0.0f) {
        correction -= (0.5f * excess / length) * diff;
        violated = true;
      }
    }
    if (violated) out = x + correction / (float)(end - ring_offsets[v]);
  }
  vstore3(out, v, positions_out);
}
