// Surface tracking, localized smoothing (Vaillant et al. 2013, section 5,
// eq. 7): beta (contacts) and gamma (creases) diffused from their sources
// over the one-rings, then Laplacian steps weighted by them. OpenCL C 1.2.
// CPU reference: CpuSurfaceTracking::smooth
// (lib/src/tracking/surface_tracking.cpp). The rows filtered to the
// neighbours within each vertex's smoothing radius: near_offsets,
// near_neighbours; reach[v] (active vertices): the first diffusion step at
// which v may change, ISK_REACH_NONE out of reach of every contact and
// crease.
//
// Every per-vertex array and the one-rings are in the device's vertex order
// and layout described in tracking/project.cl.

#include "common.h"

// Eq. 7: one localized Laplacian step, the offset d to the near centroid
// weighted by beta (b, contacts) and the tangential part of it by gamma
// (c, creases).
ISK_INLINE float3 smoothing_step(const float3 x, const float3 d,
                                 const float3 tangential, const float b,
                                 const float c) {
  return x + b * d + (1.0f - b) * c * tangential;
}

// Marks v and the vertices whose rows list it (reverse near rows) as in
// reach from diffusion step `step` on: pushed, so that no vertex reads its
// neighbours to learn it. Concurrent writers store the same value.
ISK_INLINE void push_reach(const uint v, const uint step,
                           __global const uint* reverse_offsets,
                           __global const int* reverse_neighbours,
                           __global uchar* reach) {
  const uchar r = (uchar)min(step, (uint)ISK_REACH_MAX);
  const uint end = reverse_offsets[v + 1];
  for (uint i = reverse_offsets[v]; i < end; ++i) {
    const int w = reverse_neighbours[i];
    if (reach[w] > r) reach[w] = r;
  }
}

// The crease gate (CpuSurfaceTracking::smooth, creaseGate): a crease
// vertex's source value of gamma, from its ring's vector area now and
// skinned, the offset of its near centroid from it now and skinned (shift,
// skinned_shift), its near neighbours' mean rest length, and the largest
// stretch of a spoke beyond its skinned length in rest lengths; 1 where the
// ring has no area now or the skinned ring none.
ISK_INLINE float crease_gate(const float3 area, const float3 skinned_area,
                             const float3 shift, const float3 skinned_shift,
                             const float mean_length, const float stretch) {
  const float length =
      sqrt(area.x * area.x + area.y * area.y + area.z * area.z);
  const float skinned_length2 = skinned_area.x * skinned_area.x +
                                skinned_area.y * skinned_area.y +
                                skinned_area.z * skinned_area.z;
  if (!(length > 0.0f) || !isfinite(length) || !(skinned_length2 > 0.0f) ||
      !isfinite(skinned_length2) || !(mean_length > 0.0f))
    return 1.0f;
  const float ratio = (area.x * skinned_area.x + area.y * skinned_area.y +
                       area.z * skinned_area.z) /
                      skinned_length2;
  const float crushed = clamp((ISK_CREASE_AREA_NONE - ratio) /
                                  (ISK_CREASE_AREA_NONE - ISK_CREASE_AREA_FULL),
                              0.0f, 1.0f);
  const float3 unit = area / length;
  float3 moved = shift - skinned_shift;
  moved -= (moved.x * unit.x + moved.y * unit.y + moved.z * unit.z) * unit;
  const float moved_length =
      sqrt(moved.x * moved.x + moved.y * moved.y + moved.z * moved.z);
  const float shifted =
      clamp((moved_length / mean_length - ISK_CREASE_SHIFT_NONE) /
                (ISK_CREASE_SHIFT_FULL - ISK_CREASE_SHIFT_NONE),
            0.0f, 1.0f);
  const float stretched =
      clamp((stretch - ISK_CREASE_STRETCH_NONE) /
                (ISK_CREASE_STRETCH_FULL - ISK_CREASE_STRETCH_NONE),
            0.0f, 1.0f);
  return max(max(crushed, shifted), stretched);
}

// The largest stretch of a spoke of v's ring beyond its skinned length, in
// rest lengths (ring_lengths); skinned positions in the input's order
// (source).
ISK_INLINE float spoke_stretch(const uint v, __global const float* positions,
                               __global const float* skinned_positions,
                               __global const int* source,
                               __global const uint* ring_offsets,
                               __global const int* ring_neighbours,
                               __global const float* ring_lengths) {
  const float3 x = vload3(v, positions);
  const float3 sx = vload3(source[v], skinned_positions);
  float stretch = 0.0f;
  const uint end = ring_offsets[v + 1];
  for (uint i = ring_offsets[v]; i < end; ++i) {
    const int j = ring_neighbours[i];
    const float3 a = vload3(j, positions) - x;
    const float3 b = vload3(source[j], skinned_positions) - sx;
    const float now = sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
    const float skinned = sqrt(b.x * b.x + b.y * b.y + b.z * b.z);
    stretch = max(stretch, (now - skinned) / ring_lengths[i]);
  }
  return stretch;
}

// The vector area of v's closed ring at `positions`: the sum of
// (x_i - x) x (x_i+1 - x) in ring order. With `mapped` the positions are in
// the input's order (source maps the device's vertex to it).
ISK_INLINE float3 ring_area(const uint v, __global const float* positions,
                            __global const uint* ring_offsets,
                            __global const int* ring_neighbours,
                            __global const int* source, const bool mapped) {
  const float3 x = vload3(mapped ? source[v] : (int)v, positions);
  const uint begin = ring_offsets[v];
  const uint end = ring_offsets[v + 1];
  float3 area = (float3)(0.0f);
  for (uint i = begin; i < end; ++i) {
    const uint j = i + 1 < end ? i + 1 : begin;
    const int a = ring_neighbours[i];
    const int b = ring_neighbours[j];
    area += cross(vload3(mapped ? source[a] : a, positions) - x,
                  vload3(mapped ? source[b] : b, positions) - x);
  }
  return area;
}

// The offset of v's near centroid (the neighbours within its smoothing
// radius) from v at `positions` (mapped: as for ring_area).
ISK_INLINE float3 near_shift(const uint v, __global const float* positions,
                             __global const uint* near_offsets,
                             __global const int* near_neighbours,
                             __global const int* source, const bool mapped) {
  const uint begin = near_offsets[v];
  const int near = (int)(near_offsets[v + 1] - begin);
  float3 centroid = (float3)(0.0f);
  for (int i = 0; i < near; ++i) {
    const int j = near_neighbours[begin + i];
    centroid += vload3(mapped ? source[j] : j, positions);
  }
  centroid /= (float)max(near, 1);
  return centroid - vload3(mapped ? source[v] : (int)v, positions);
}

// (beta, gamma): beta = 1 on contact vertices, gamma on crease vertices
// their source value (the crease gate when `gated`, else 1; also written to
// crease_sources, 0 elsewhere), 0 elsewhere, in both buffers (the diffusion
// of active vertices writes only the vertices in reach; the others stay 0
// in either). Contact vertices and crease vertices with a source value put
// themselves and the vertices whose rows list them in reach of the first
// diffusion step (track_begin cleared reach). near_mean_lengths: the near
// neighbours' mean rest length per vertex; ring_lengths: the rest length of
// each ring edge; skinned_positions in the input's order (source maps the
// device's vertex to it).
__kernel void track_beta_init(
    const uint vertex_count, __global const uchar* states,
    __global float2* beta, __global float2* beta_other,
    __global const uint* reverse_offsets,
    __global const int* reverse_neighbours, __global uchar* reach,
    const uint gated, __global const uchar* kinds,
    __global const uint* ring_offsets, __global const int* ring_neighbours,
    __global const uint* near_offsets, __global const int* near_neighbours,
    __global const float* near_mean_lengths, __global const float* positions,
    __global const float* skinned_positions, __global const int* source,
    __global const float* ring_lengths, __global float* crease_sources) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const uchar state = states[v];
  float value = 0.0f;
  if (state == ISK_TRACK_CREASE) {
    value = 1.0f;
    if (gated && kinds[v] == ISK_RING_CLOSED &&
        near_offsets[v + 1] > near_offsets[v])
      value = crease_gate(
          ring_area(v, positions, ring_offsets, ring_neighbours, source, false),
          ring_area(v, skinned_positions, ring_offsets, ring_neighbours, source,
                    true),
          near_shift(v, positions, near_offsets, near_neighbours, source,
                     false),
          near_shift(v, skinned_positions, near_offsets, near_neighbours,
                     source, true),
          near_mean_lengths[v],
          spoke_stretch(v, positions, skinned_positions, source, ring_offsets,
                        ring_neighbours, ring_lengths));
  }
  crease_sources[v] = value;
  const float2 b = (float2)(state == ISK_TRACK_CONTACT ? 1.0f : 0.0f, value);
  beta[v] = b;
  beta_other[v] = b;
  if (b.x > 0.0f || b.y > 0.0f) {
    reach[v] = 1;
    push_reach(v, 1, reverse_offsets, reverse_neighbours, reach);
  }
}

// Diffusion step `step` (1, 2, ...) of (beta, gamma) over the neighbours
// within the vertex's smoothing radius (rest distance): its one-ring
// filtered once by the host, in ring order, as compressed rows
// (near_offsets, near_neighbours), so no ring length is read per step.
// beta_in -> beta_out, of the channels whose `channels` entry is 1: contact
// vertices stay at 1, the others take the mean of themselves and their
// neighbours
// (duplicates, with no ring, keep theirs), crease vertices at least their
// source value (crease_sources). With active = 1 only the
// vertices in reach of this step do it (the others are 0 and have no
// neighbour that is not, so the mean would leave them 0); a vertex left
// non-zero in a channel that `next_channels` (the next step's) diffuses
// puts the vertices whose rows list it in reach of the next step.
__kernel void track_beta_diffuse(
    const uint vertex_count, __global const uchar* states,
    __global const uint* near_offsets, __global const int* near_neighbours,
    __global const float2* beta_in, __global float2* beta_out,
    const float2 channels, const uint active, const uint step,
    const float2 next_channels, __global const uint* reverse_offsets,
    __global const int* reverse_neighbours, __global uchar* reach,
    __global const float* crease_sources) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  if (active && reach[v] > step) return;
  const float2 b = beta_in[v];
  float2 sum = b;
  float count = 1.0f;
  const uint end = near_offsets[v + 1];
  for (uint i = near_offsets[v]; i < end; ++i) {
    sum += beta_in[near_neighbours[i]];
    count += 1.0f;
  }
  float2 out = sum / count;
  if (channels.x == 0.0f) out.x = b.x;
  if (channels.y == 0.0f) out.y = b.y;
  if (states[v] == ISK_TRACK_CONTACT) out.x = 1.0f;
  if (states[v] == ISK_TRACK_CREASE) out.y = max(out.y, crease_sources[v]);
  beta_out[v] = out;
  if (active && ((out.x != 0.0f && next_channels.x != 0.0f) ||
                 (out.y != 0.0f && next_channels.y != 0.0f)))
    push_reach(v, step + 1, reverse_offsets, reverse_neighbours, reach);
}

// One Laplacian step over the neighbours within the smoothing radius (the
// filtered rows of track_beta_diffuse), positions_in -> positions_out: full,
// weighted by beta (eq. 7), and tangential (normal to the whole one-ring)
// weighted by (1 - beta) gamma; `weights` (0 or 1 each) switches the two
// off once their steps are done. Every vertex is written when
// active_reach is 0; otherwise only those in reach of diffusion step
// active_reach (the others have beta = gamma = 0), and with
// `copy_marching` (the first step) the vertices still marching too: the
// only ones the rounds leave different in the two buffers (track_relax).
__kernel void track_smooth(
    const uint vertex_count, __global const uchar* rules,
    __global const uchar* kinds, __global const uint* ring_offsets,
    __global const int* ring_neighbours, __global const uint* near_offsets,
    __global const int* near_neighbours, __global const float2* beta,
    __global const float* positions_in, __global float* positions_out,
    const float2 weights, const uint active_reach, __global const uchar* reach,
    __global const uchar* states, const uint copy_marching) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  if (active_reach > 0 && reach[v] > active_reach &&
      !(copy_marching && states[v] == ISK_TRACK_MARCHING))
    return;
  const float3 x = vload3(v, positions_in);
  float3 out = x;
  const float2 bc = beta[v] * weights;
  if ((bc.x > 0.0f || bc.y > 0.0f) && rules[v] != ISK_RULE_FIXED) {
    float3 centroid = (float3)(0.0f);
    const uint near_begin = near_offsets[v];
    const int near = (int)(near_offsets[v + 1] - near_begin);
    for (int i = 0; i < near; ++i)
      centroid += vload3(near_neighbours[near_begin + i], positions_in);
    centroid /= (float)max(near, 1);
    const float3 d = near > 0 ? centroid - x : (float3)(0.0f);
    float3 tangential = (float3)(0.0f);
    if (bc.y > 0.0f && near > 0 && kinds[v] == ISK_RING_CLOSED) {
      const uint begin = ring_offsets[v];
      const uint end = ring_offsets[v + 1];
      float3 normal = (float3)(0.0f);
      // Each neighbour loaded once: the next edge starts where this ends.
      const float3 first = vload3(ring_neighbours[begin], positions_in) - x;
      float3 a = first;
      for (uint i = begin; i < end; ++i) {
        const float3 b = i + 1 < end
                             ? vload3(ring_neighbours[i + 1], positions_in) - x
                             : first;
        normal += cross(a, b);
        a = b;
      }
      const float length =
          sqrt(normal.x * normal.x + normal.y * normal.y + normal.z * normal.z);
      if (length > 0.0f && isfinite(length)) {  // inf: no direction
        normal /= length;
        tangential =
            d - (d.x * normal.x + d.y * normal.y + d.z * normal.z) * normal;
      }
    }
    out = smoothing_step(x, d, tangential, bc.x, bc.y);
  }
  vstore3(out, v, positions_out);
}
