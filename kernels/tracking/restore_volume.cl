// Surface tracking, volume restoration (our addition, docs/algorithm.md):
// after the smoothing, each closed component of the welded mesh that lost
// volume moves the vertices tracking moved inward from their skinned
// position back out along the skinned normal, by one fraction per component;
// what they cannot give back, the contact bulge pushes out over a band
// around the contacts (only on frames where some component needs it).
// OpenCL C 1.2. CPU reference: CpuSurfaceTracking::restoreVolume and
// volumeRestoreWeight / volumeRestoreFraction / volumeRestoreLimit /
// volumeRestoreDistance / volumeRestoreBackFactor / volumeRestoreStep /
// contactBulgeNeeded / contactBandStep / contactBulgeWeight /
// contactBulgeFraction
// (lib/src/tracking/surface_tracking.cpp); the groups are
// TrackingMesh::VolumeGroups.
//
// Per-vertex arrays are in the device's vertex order (tracking/project.cl);
// the skinned positions and normals are in the mesh's order, device index k
// reading skinned[source[k]]. Sums go by chunks of at most
// ISK_VOLUME_CHUNK triangles or vertices of one group (int4 per chunk:
// group, first, end), then by group over its chunks in order
// (track_restore_fractions): the same sums on every run.

#include "abi.h"
#include "common.h"

// Six times the volume of each chunk's triangles (corners: 3 device
// indices per triangle, wound outward) about its group's first corner
// (group_origins: a device index per group).
__kernel void track_volume_chunks(const uint chunk_count,
                                  __global const int4* chunks,
                                  __global const int* corners,
                                  __global const int* group_origins,
                                  __global const float* positions,
                                  __global float* chunk_volumes) {
  const uint k = get_global_id(0);
  if (k >= chunk_count) return;
  const int4 chunk = chunks[k];
  const float3 c0 = vload3(group_origins[chunk.x], positions);
  float sum = 0.0f;
  for (int t = chunk.y; t < chunk.z; ++t) {
    const float3 a = vload3(corners[3 * t], positions) - c0;
    const float3 b = vload3(corners[3 * t + 1], positions) - c0;
    const float3 c = vload3(corners[3 * t + 2], positions) - c0;
    sum += dot(a, cross(b, c));
  }
  chunk_volumes[k] = sum;
}

// The contact bulge's band: 1 on the contact vertices, 0 elsewhere; 0
// everywhere when no group needs the bulge (needed[0], set by
// track_restore_fractions): the grow and the probe then have nothing to do.
__kernel void track_bulge_band_init(const uint vertex_count,
                                    __global const uchar* states,
                                    __global const int* needed,
                                    __global float* band) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  band[v] = needed[0] && states[v] == ISK_TRACK_CONTACT ? 1.0f : 0.0f;
}

// One ring more of the band (contactBandStep): the largest of the vertex's
// own and each neighbour's less the edge's rest length over the vertex's
// reach (contact_bulge_radius of its diagonal); 0 when no group needs the
// bulge.
__kernel void track_bulge_band_grow(
    const uint vertex_count, __global const uint* ring_offsets,
    __global const int* ring_neighbours, __global const float* ring_lengths,
    __global const float* reaches, __global const int* needed,
    __global const float* band, __global float* next) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  if (!needed[0]) {
    next[v] = 0.0f;
    return;
  }
  const float reach = reaches[v];
  float b = band[v];
  for (uint i = ring_offsets[v]; i < ring_offsets[v + 1]; ++i)
    b = fmax(b, band[ring_neighbours[i]] - ring_lengths[i] / reach);
  next[v] = b;
}

// Each listed vertex's weight (volumeRestoreWeight: the inward move from
// the skinned position along the skinned normal times its sign (outward),
// times 1 - gamma, of the converged vertices where beta = 0, faded by the
// share of their ring that moves too; 0 for the others), one work-item per
// entry of the groups' vertex lists.
__kernel void track_restore_weights(
    const uint entry_count, __global const int* entries,
    __global const uchar* states, __global const float2* beta,
    __global const float* positions, __global const float* skinned,
    __global const float* skinned_normals, __global const int* source,
    __global const float* signs, __global const int* groups,
    __global const uint* ring_offsets, __global const int* ring_neighbours,
    __global float* weights) {
  const uint e = get_global_id(0);
  if (e >= entry_count) return;
  const int v = entries[e];
  const float2 bc = beta[v];
  float w = 0.0f;
  if (states[v] == ISK_TRACK_CONVERGED && !(bc.x > 0.0f)) {
    const float3 n = vload3(source[v], skinned_normals);
    const float length = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    if (length > 0.0f && isfinite(length)) {
      const float3 d = vload3(v, positions) - vload3(source[v], skinned);
      const float inward =
          -signs[v] * (d.x * n.x + d.y * n.y + d.z * n.z) / length;
      if (inward > 0.0f) w = inward * (1.0f - bc.y);
    }
  }
  if (w > 0.0f) {
    const uint begin = ring_offsets[v], end = ring_offsets[v + 1];
    int moving = 0;
    for (uint i = begin; i < end; ++i) {
      const int u = ring_neighbours[i];
      moving += states[u] == ISK_TRACK_CONVERGED && !(beta[u].x > 0.0f) &&
                groups[u] >= 0;
    }
    if (end > begin) w *= (float)moving / (float)(end - begin);
  }
  weights[v] = w;
}

// Each chunk's sum of its vertices' weights (track_restore_weights) times
// their rest areas, in the chunk's order (track_restore_fractions adds the
// chunks up).
__kernel void track_restore_weighted(const uint chunk_count,
                                     __global const int4* chunks,
                                     __global const int* entries,
                                     __global const float* areas,
                                     __global const float* weights,
                                     __global float* chunk_weighted) {
  const uint k = get_global_id(0);
  if (k >= chunk_count) return;
  const int4 chunk = chunks[k];
  float sum = 0.0f;
  for (int e = chunk.y; e < chunk.z; ++e) {
    const int v = entries[e];
    sum += weights[v] * areas[v];
  }
  chunk_weighted[k] = sum;
}

// Each chunk's vertices' bulge weights (contactBulgeWeight: band times
// 1 - gamma times the mean rest length of the ring's edges, of the
// converged vertices where beta = 0 away from other components, times their
// clearance: tracking/bulge_clearance.cl; 0 off the band), written per
// vertex, and their sum weighted by the vertices' rest areas.
__kernel void track_bulge_weights(
    const uint chunk_count, __global const int4* chunks,
    __global const int* entries, __global const uchar* states,
    __global const float2* beta, __global const float* areas,
    __global const uint* ring_offsets, __global const float* ring_lengths,
    __global const float* band, __global const uchar* near_other,
    __global const float* clearance, __global float* bulge_weights,
    __global float* chunk_bulge_weighted) {
  const uint k = get_global_id(0);
  if (k >= chunk_count) return;
  const int4 chunk = chunks[k];
  float sum = 0.0f;
  for (int e = chunk.y; e < chunk.z; ++e) {
    const int v = entries[e];
    const float2 bc = beta[v];
    const uint begin = ring_offsets[v], end = ring_offsets[v + 1];
    float u = 0.0f;
    if (end > begin && states[v] == ISK_TRACK_CONVERGED && !(bc.x > 0.0f) &&
        !near_other[v] && band[v] > 0.0f) {
      float length = 0.0f;
      for (uint i = begin; i < end; ++i) length += ring_lengths[i];
      u = band[v] * (1.0f - bc.y) * (length / (float)(end - begin)) *
          clearance[v];
    }
    bulge_weights[v] = u;
    sum += u * areas[v];
  }
  chunk_bulge_weighted[k] = sum;
}

// A group's volume: the sum of its triangle chunks over 6.
ISK_INLINE float group_volume(const uint g,
                              __global const int* triangle_chunk_offsets,
                              __global const float* chunk_volumes) {
  float volume = 0.0f;
  for (int k = triangle_chunk_offsets[g]; k < triangle_chunk_offsets[g + 1];
       ++k)
    volume += chunk_volumes[k];
  return volume / 6.0f;
}

// Each group's fraction (volumeRestoreFraction): its missing volume (rest
// less its volume, also written to `missing`) over the sum of its vertex
// chunks, in [0, limit]. With the contact bulge on (contactBulgeNeeded),
// what the inward moves cannot give back at `limit` goes to bulge_missing
// (0 where they can) and any group with some sets needed[0] (cleared
// before); with it off, bulge_missing is 0.
__kernel void track_restore_fractions(
    const uint group_count, __global const int* triangle_chunk_offsets,
    __global const int* vertex_chunk_offsets,
    __global const float* chunk_volumes, __global const float* chunk_weighted,
    __global const float* rest_volumes, const float limit,
    __global float* fractions, __global float* missing_volumes, const int bulge,
    __global float* bulge_missing, __global volatile int* needed) {
  const uint g = get_global_id(0);
  if (g >= group_count) return;
  float weighted = 0.0f;
  for (int k = vertex_chunk_offsets[g]; k < vertex_chunk_offsets[g + 1]; ++k)
    weighted += chunk_weighted[k];
  const float missing =
      rest_volumes[g] - group_volume(g, triangle_chunk_offsets, chunk_volumes);
  missing_volumes[g] = missing;
  fractions[g] = weighted > 0.0f && missing > 0.0f
                     ? fmin(missing / weighted, limit)
                     : 0.0f;
  const float rest = missing - limit * weighted;
  bulge_missing[g] = bulge && rest > 0.0f ? rest : 0.0f;
  if (bulge && rest > 0.0f) atomic_or(needed, 1);
}

// Each group's contact bulge fraction (contactBulgeFraction): its
// bulge_missing over the sum of its bulge chunks, in [0, bulge_limit].
__kernel void track_bulge_fractions(const uint group_count,
                                    __global const int* vertex_chunk_offsets,
                                    __global const float* chunk_bulge_weighted,
                                    __global const float* bulge_missing,
                                    const float bulge_limit,
                                    __global float* bulge_fractions) {
  const uint g = get_global_id(0);
  if (g >= group_count) return;
  float bulge_weighted = 0.0f;
  for (int k = vertex_chunk_offsets[g]; k < vertex_chunk_offsets[g + 1]; ++k)
    bulge_weighted += chunk_bulge_weighted[k];
  const float rest = bulge_missing[g];
  bulge_fractions[g] = rest > 0.0f && bulge_weighted > 0.0f
                           ? fmin(rest / bulge_weighted, bulge_limit)
                           : 0.0f;
}

// After the step, the secant step back of each group that went past its
// rest volume (volumeRestoreCorrection, volumeRestoreBackFactor): its
// volume now (chunk_volumes of the stepped positions) less its volume
// before is what it gained; where that exceeds what it missed, its
// fraction is scaled by missing / gained and `back` receives the change
// (corrected / fraction - 1, negative; missing / gained - 1 where only the
// bulge stepped), 0 elsewhere.
__kernel void track_restore_correct(
    const uint group_count, __global const int* triangle_chunk_offsets,
    __global const float* chunk_volumes, __global const float* rest_volumes,
    __global const float* missing_volumes, __global float* fractions,
    __global float* previous, __global float* back,
    __global const float* bulge_fractions) {
  const uint g = get_global_id(0);
  if (g >= group_count) return;
  const float missing = missing_volumes[g];
  const float fraction = fractions[g];
  const float gained = group_volume(g, triangle_chunk_offsets, chunk_volumes) -
                       (rest_volumes[g] - missing);
  float corrected = fraction;
  if (fraction > 0.0f && missing > 0.0f && gained > missing)
    corrected = fraction * (missing / gained);
  previous[g] = fraction;
  fractions[g] = corrected;
  if (fraction > 0.0f)
    back[g] = corrected / fraction - 1.0f;
  else
    back[g] = bulge_fractions[g] > 0.0f && missing > 0.0f && gained > missing
                  ? missing / gained - 1.0f
                  : 0.0f;
}

// The step (volumeRestoreStep, volumeRestoreDistance): each weighted vertex
// moved out along its unit skinned normal (times its sign: outward) by its
// weight times its group's fraction, capped at the vertex's limit
// (volumeRestoreLimit: volume_restore, at most ISK_VOLUME_NEAR_LIMIT near
// another component of the mesh), plus its bulge weight times its group's
// bulge fraction capped at contact_bulge (bulge on), times its group's
// factor (1, then the secant step back's, volumeRestoreBackFactor).
__kernel void track_restore_apply(
    const uint vertex_count, __global const int* groups,
    __global const float* weights, __global const float* fractions,
    __global const float* factors, __global const uchar* near_other,
    const float volume_restore, __global const float* skinned_normals,
    __global const int* source, __global const float* signs,
    __global float* positions, const int bulge,
    __global const float* bulge_weights, __global const float* bulge_fractions,
    const float contact_bulge) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const int g = groups[v];
  if (g < 0) return;
  const float w = weights[v];
  const float u = bulge ? bulge_weights[v] : 0.0f;
  if (!(w > 0.0f || u > 0.0f)) return;
  const float limit = near_other[v]
                          ? fmin(volume_restore, ISK_VOLUME_NEAR_LIMIT)
                          : volume_restore;
  const float distance =
      fmin(fractions[g], limit) * factors[g] * w +
      fmin(bulge_fractions[g], contact_bulge) * factors[g] * u;
  const float3 n = vload3(source[v], skinned_normals);
  const float length = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  vstore3(vload3(v, positions) + (signs[v] * distance / length) * n, v,
          positions);
}
