// Surface tracking, the contact bulge's clearance probe (our addition,
// docs/algorithm.md): before the bulge weights, each band vertex samples the
// composed field at its probe, out along its push (the skinned normal times
// its sign) by its largest push times contact_bulge_clearance; where another
// part's surface is within that reach the field there reaches the vertex's
// iso value and its push fades out (no bulge into a part it faces).
// OpenCL C 1.2. CPU reference: CpuSurfaceTracking::restoreVolume and
// contactBulgeClearance (lib/src/tracking/surface_tracking.cpp). Built with
// the fields' options and the broad phase's, as tracking/project.cl: the
// probe samples the composed field as the march does (sample_tracking), the
// fields of the vertex's home neighbourhood only, with the same value.
//
// Device order as in tracking/restore_volume.cl: per-vertex arrays and rings
// by device index; skinned normals in the mesh's order (device index k
// reads source[k]).

#include "tracking/sample_tracking.cl"

// clearance[v]: contactBulgeClearance of the field at v's probe, for the
// vertices whose bulge weight can be above 0 (track_bulge_weights: converged,
// in the band, beta = 0, away from other components); 1 for the others
// (their bulge weight is 0 whatever it is) and everywhere when `reach` (the
// probe's distance in mean ring edge lengths) is 0.
__kernel void track_bulge_clearance(
    const uint vertex_count, __global const uchar* states,
    __global const float* band, __global const float* positions,
    __global const float* skinned_normals, __global const int* source,
    __global const float* signs, __global const uint* ring_offsets,
    __global const float* ring_lengths, __global const float* iso_values,
    const float reach, __global const float2* beta,
    __global const uchar* near_other, ISK_TRACKING_PARAMS, ISK_FIELD_PARAMS,
    ISK_COMPOSITION_PARAMS, __global float* clearance) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const uint begin = ring_offsets[v], end = ring_offsets[v + 1];
  float c = 1.0f;
  if (reach > 0.0f && end > begin && states[v] == ISK_TRACK_CONVERGED &&
      band[v] > 0.0f && !(beta[v].x > 0.0f) && !near_other[v]) {
    float length = 0.0f;
    for (uint i = begin; i < end; ++i) length += ring_lengths[i];
    const float distance = reach * (length / (float)(end - begin));
    const float3 n = vload3(source[v], skinned_normals);
    const float n_len = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    // As the CPU reference's volumeRestoreStep: no step along a zero normal.
    const float3 probe =
        vload3(v, positions) +
        (n_len > 0.0f ? signs[v] * distance / n_len : 0.0f) * n;
    // Only the composed value is read: every field the value bounds skip
    // is below it (sample_tracking), whatever the other parts' slack.
    float4 home_sample, other;
    const float4 f = sample_tracking(
        ISK_FIELD_ARGS, ISK_COMPOSITION_ARGS, ISK_TRACKING_ARGS, probe,
        home_fields[v],
        (contact_flags & ISK_CONTACT_VALUE_BOUNDS) != 0, INFINITY,
        &home_sample, &other);
    c = clamp((iso_values[v] - f.x) / ISK_BULGE_CLEARANCE_WIDTH, 0.0f, 1.0f);
  }
  clearance[v] = c;
}
