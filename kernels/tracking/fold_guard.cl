// Surface tracking, the fold guard (our addition, docs/algorithm.md): within
// the strain limit's steps (tracking/strain_limit.cl), each vertex takes the
// largest fold weight of the triangles within fold_rings rings of it, and a
// ring edge's limit goes from strain_limit towards the fold limit by the
// larger weight of its ends. A triangle has folded over when its normal, at
// the skinned positions plus the steps' offsets, opposes its skinned normal
// and the sum of its corners' skinned normals, and the skinned triangle does
// not oppose that sum. The tilt guard also weighs the triangles turned
// steeply from both. OpenCL C 1.2. CPU reference:
// CpuSurfaceTracking::weighFolds (lib/src/tracking/surface_tracking.cpp).
//
// Device order as in tracking/strain_limit.cl: offsets, rings, marks and the
// fold rows by device index; skinned positions and normals in the mesh's
// order (device index k reads source[k]).

#include "common.h"

// A triangle's normal (counter-clockwise, unnormalized), term by term as in
// the CPU reference (triangleNormal).
float3 triangle_normal(const float3 p0, const float3 p1, const float3 p2) {
  const float3 a = p1 - p0, b = p2 - p0;
  return (float3)(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z,
                  a.x * b.y - a.y * b.x);
}

float dot3(const float3 a, const float3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

// x / ISK_FOLD_RAMP clamped to [0, 1] (foldRamp).
float fold_ramp(const float x) { return clamp(x / ISK_FOLD_RAMP, 0.0f, 1.0f); }

// The triangles' frames (foldFrame), once a frame: float4 pairs per
// triangle, (skinned unit normal, allowance) and (unit sum of the corners'
// skinned normals, 0). The allowance is how far the skinned triangle does
// not oppose that sum, ramped over ISK_FOLD_RAMP: 0 where skinning folded it
// itself (not the tracking's to undo) or where it is degenerate.
__kernel void track_fold_frames(const uint triangle_count,
                                __global const float* skinned,
                                __global const float* skinned_normals,
                                __global const int* source,
                                __global const int* fold_corners,
                                __global float4* frames) {
  const uint t = get_global_id(0);
  if (t >= triangle_count) return;
  float3 q[3], n[3];
  for (int c = 0; c < 3; ++c) {
    const int k = source[fold_corners[3 * t + c]];
    q[c] = vload3(k, skinned);
    n[c] = vload3(k, skinned_normals);
  }
  const float3 normal = triangle_normal(q[0], q[1], q[2]);
  const float3 sum = n[0] + n[1] + n[2];
  const float normal_length = sqrt(dot3(normal, normal));
  const float sum_length = sqrt(dot3(sum, sum));
  float4 a = (float4)(0.0f), b = (float4)(0.0f);
  if (normal_length > 0.0f && sum_length > 0.0f) {
    const float3 s = normal / normal_length, e = sum / sum_length;
    a = (float4)(s, fold_ramp(dot3(s, e) + ISK_FOLD_RAMP));
    b = (float4)(e, 0.0f);
  }
  frames[2 * t] = a;
  frames[2 * t + 1] = b;
}

// A check recomputes only what its inputs changed (unless `all`, the
// first check of a series, which computes everything): a triangle the steps
// marked (a corner moved), then the vertex weights level by level (level 0
// from the triangles, level r + 1 one ring more than level r; levels: one
// row of #V floats per level, kept between checks), each vertex flagged
// when an input of its level changed (flags: a row of #V uchars per level,
// then one for the commit). A value that comes out the same flags nothing
// further. Every kernel clears the marks it reads.

// Each triangle's fold weight (foldWeight), in [0, 1]: how far its normal
// at the skinned positions plus the offsets opposes both its skinned normal
// and the sum of its corners' skinned normals, each cosine ramped over
// ISK_FOLD_RAMP, times its allowance. With the tilt guard (tilt_scale > 0),
// the larger of that and tilt_scale times how far the normal turned past
// tilt_cosine from both (tiltWeight). The weight depends on the corners'
// offsets alone (the frames are the frame's): a triangle the steps did not
// mark keeps its weight. Where a weight changes, its corners' level 0 is
// flagged.
__kernel void track_weigh_triangles(
    const uint triangle_count, __global const float* offsets,
    __global const float* skinned, __global const int* source,
    __global const int* fold_corners, __global const float4* frames,
    __global float* triangle_weights, const float tilt_cosine,
    const float tilt_scale, __global uchar* dirty_triangles, const int all,
    __global uchar* flags) {
  const uint t = get_global_id(0);
  if (t >= triangle_count) return;
  if (!all && !dirty_triangles[t]) return;
  dirty_triangles[t] = 0;
  const float4 a = frames[2 * t];
  float weight = 0.0f;
  if (a.w > 0.0f) {
    float3 p[3];
    for (int c = 0; c < 3; ++c) {
      const int k = fold_corners[3 * t + c];
      p[c] = vload3(source[k], skinned) + vload3(k, offsets);
    }
    const float3 now = triangle_normal(p[0], p[1], p[2]);
    const float length = sqrt(dot3(now, now));
    if (length > 0.0f) {
      const float along_sum = dot3(now, frames[2 * t + 1].xyz) / length;
      const float along_skinned = dot3(now, a.xyz) / length;
      weight = fold_ramp(-along_sum) * fold_ramp(-along_skinned) * a.w;
      if (tilt_scale > 0.0f)
        weight = fmax(weight, tilt_scale * (fold_ramp(tilt_cosine - along_sum) *
                                            fold_ramp(tilt_cosine -
                                                      along_skinned) *
                                            a.w));
    }
  }
  if (!all && weight == triangle_weights[t]) return;
  triangle_weights[t] = weight;
  if (!all)
    for (int c = 0; c < 3; ++c) flags[fold_corners[3 * t + c]] = 1;
}

// Flags the next level of vertex v and of the vertices whose rings list it
// (a level one ring out reads v), or v's commit (`ring` 0).
ISK_INLINE void flag_next(const uint v, __global uchar* next, const int ring,
                          __global const uint* reverse_offsets,
                          __global const int* reverse_neighbours) {
  next[v] = 1;
  if (!ring) return;
  for (uint i = reverse_offsets[v]; i < reverse_offsets[v + 1]; ++i)
    next[reverse_neighbours[i]] = 1;
}

// Level 0 of a vertex: the largest weight of the triangles with a corner in
// its welded group (fold rows: compressed, per device index).
// `next_ring`: whether the next level grows a ring (else it is the commit).
__kernel void track_weigh_folds(
    const uint vertex_count, __global const uint* fold_offsets,
    __global const int* fold_triangles,
    __global const float* triangle_weights, __global float* level,
    __global uchar* flags, __global uchar* next_flags, const int next_ring,
    __global const uint* reverse_offsets,
    __global const int* reverse_neighbours, const int all) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  if (!all && !flags[v]) return;
  flags[v] = 0;
  float weight = 0.0f;
  for (uint i = fold_offsets[v]; i < fold_offsets[v + 1]; ++i)
    weight = fmax(weight, triangle_weights[fold_triangles[i]]);
  if (!all && weight == level[v]) return;
  level[v] = weight;
  if (!all)
    flag_next(v, next_flags, next_ring, reverse_offsets, reverse_neighbours);
}

// One ring more: the largest weight of the vertex and its ring in the level
// before.
__kernel void track_grow_folds(
    const uint vertex_count, __global const float* level_in,
    __global float* level, __global uchar* flags, __global uchar* next_flags,
    const int next_ring, __global const uint* ring_offsets,
    __global const int* ring_neighbours, __global const uint* reverse_offsets,
    __global const int* reverse_neighbours, const int all) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  if (!all && !flags[v]) return;
  flags[v] = 0;
  float weight = level_in[v];
  for (uint i = ring_offsets[v]; i < ring_offsets[v + 1]; ++i)
    weight = fmax(weight, level_in[ring_neighbours[i]]);
  if (!all && weight == level[v]) return;
  level[v] = weight;
  if (!all)
    flag_next(v, next_flags, next_ring, reverse_offsets, reverse_neighbours);
}

// The last level's weights replace the ones the steps read; where one
// changed, the vertex and the tracked vertices whose rings list it are
// marked active for the next step (their edges' limits changed).
__kernel void track_commit_folds(
    const uint vertex_count, const uint march_count,
    __global const float* level, __global float* weights,
    __global uchar* flags, __global uchar* active,
    __global const uint* reverse_offsets,
    __global const int* reverse_neighbours, const int all) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  if (!all && !flags[v]) return;
  flags[v] = 0;
  const float w = level[v];
  if (w == weights[v]) return;
  weights[v] = w;
  if (v < march_count) active[v] = 1;
  for (uint i = reverse_offsets[v]; i < reverse_offsets[v + 1]; ++i) {
    const int u = reverse_neighbours[i];
    if ((uint)u < march_count) active[u] = 1;
  }
}
