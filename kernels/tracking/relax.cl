// Surface tracking, tangential relaxation (Vaillant et al. 2013, section 5,
// eq. 5, 6): each marching vertex moves towards its ring's mean value
// centroid within the tangent plane of the surface it marches to. OpenCL C
// 1.2. CPU reference: CpuSurfaceTracking::relax
// (lib/src/tracking/surface_tracking.cpp). One-rings as compressed rows
// (ring_offsets, ring_neighbours, ring_weights); one uchar relaxation rule
// per vertex (ISK_RULE_FIXED: neither relaxed nor smoothed).
//
// Every per-vertex array and the one-rings are in the device's vertex order
// and layout described in tracking/project.cl.

#include "common.h"

// Eq. 5, 6: x moved by mu times its ring's weighted centroid offset, within
// the tangent plane of the surface it marches to (frame: signed distance,
// unit normal); mu fades the move out one unit of distance away.
ISK_INLINE float3 tangential_relaxation(const float3 x, const float3 centroid,
                                        const float4 frame) {
  const float3 unit = frame.yzw;
  const float t = fabs(frame.x) - 1.0f;
  const float mu = max(0.0f, 1.0f - t * t * t * t);
  float3 d = centroid - x;
  d -= (d.x * unit.x + d.y * unit.y + d.z * unit.z) * unit;
  return x + mu * d;
}

// Skinned-ring relaxation (skinnedRingOffset): the skinned ring's offset
// from its vertex, offset = sum_j w_j s_j - s, within the plane normal to
// the skinned normal n (not unit); the whole offset where n vanishes.
ISK_INLINE float3 skinned_ring_offset(const float3 offset, const float3 n) {
  const float length2 = n.x * n.x + n.y * n.y + n.z * n.z;
  if (!(length2 > 0.0f) || isinf(length2)) return offset;
  return offset -
         ((offset.x * n.x + offset.y * n.y + offset.z * n.z) / length2) * n;
}

// One tangential relaxation step, positions_in -> positions_out. With
// skip_stopped = 0 every vertex is written; with 1 (active vertices) only
// the marching ones: the others are the same in both buffers (track_begin
// writes both, and track_project writes a vertex that stops to both). The
// surface the vertex marches to (its iso-surface, or the contact surface
// while it marches to a contact) is taken as its last projection step
// sampled it (relax_frames: signed distance, unit normal; zero before any
// step), so relaxation samples no field. With skinned_ring = 1 the skinned
// ring's in-plane offset is taken out of the centroid (skinned positions and
// normals in the input's order: source maps the device's vertex to it).
__kernel void track_relax(
    const uint vertex_count, __global const float* positions_in,
    __global float* positions_out, __global const uchar* states,
    __global const float4* relax_frames, __global const uchar* rules,
    __global const uint* ring_offsets, __global const int* ring_neighbours,
    __global const float* ring_weights, __global const float* skinned,
    __global const float* skinned_normals, __global const int* source,
    const uint skinned_ring, const uint skip_stopped) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const bool marching = states[v] == ISK_TRACK_MARCHING;
  if (!marching && skip_stopped) return;
  const float3 x = vload3(v, positions_in);
  float3 out = x;
  const float4 frame = relax_frames[v];
  const float3 unit = frame.yzw;
  if (marching && rules[v] != ISK_RULE_FIXED &&
      unit.x * unit.x + unit.y * unit.y + unit.z * unit.z > 0.0f) {
    float3 centroid = (float3)(0.0f);
    float3 skinned_centroid = (float3)(0.0f);
    const uint end = ring_offsets[v + 1];
    for (uint i = ring_offsets[v]; i < end; ++i) {
      const int j = ring_neighbours[i];
      centroid += ring_weights[i] * vload3(j, positions_in);
      if (skinned_ring)
        skinned_centroid += ring_weights[i] * vload3(source[j], skinned);
    }
    if (skinned_ring)
      centroid -=
          skinned_ring_offset(skinned_centroid - vload3(source[v], skinned),
                              vload3(source[v], skinned_normals));
    out = tangential_relaxation(x, centroid, frame);
  }
  vstore3(out, v, positions_out);
}
