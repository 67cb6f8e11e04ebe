// Surface tracking, the contact bulge's clearance probe (our addition,
// docs/algorithm.md): before the bulge weights, each band vertex samples the
// composed field at its probe, out along its push (the skinned normal times
// its sign) by its largest push times contact_bulge_clearance; where another
// part's surface is within that reach the field there reaches the vertex's
// iso value and its push fades out (no bulge into a part it faces).
// OpenCL C 1.2. CPU reference: CpuSurfaceTracking::restoreVolume and
// contactBulgeClearance (lib/src/tracking/surface_tracking.cpp). Built with
// the fields' options, as tracking/project.cl.
//
// Device order as in tracking/restore_volume.cl: per-vertex arrays and rings
// by device index; skinned normals in the mesh's order (device index k
// reads source[k]).

#include "fields/compose.cl"

// clearance[v]: contactBulgeClearance of the field at v's probe, for the
// converged vertices in the band; 1 for the others (their bulge weight is 0
// whatever it is) and everywhere when `reach` (the probe's distance in mean
// ring edge lengths) is 0.
__kernel void track_bulge_clearance(
    const uint vertex_count, __global const uchar* states,
    __global const float* band, __global const float* positions,
    __global const float* skinned_normals, __global const int* source,
    __global const float* signs, __global const uint* ring_offsets,
    __global const float* ring_lengths, __global const float* iso_values,
    const float reach, ISK_FIELD_PARAMS, ISK_COMPOSITION_PARAMS,
    __global float* clearance) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const uint begin = ring_offsets[v], end = ring_offsets[v + 1];
  float c = 1.0f;
  if (reach > 0.0f && end > begin && states[v] == ISK_TRACK_CONVERGED &&
      band[v] > 0.0f) {
    float length = 0.0f;
    for (uint i = begin; i < end; ++i) length += ring_lengths[i];
    const float distance = reach * (length / (float)(end - begin));
    const float3 n = vload3(source[v], skinned_normals);
    const float n_len = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    // As the CPU reference's volumeRestoreStep: no step along a zero normal.
    const float3 probe =
        vload3(v, positions) +
        (n_len > 0.0f ? signs[v] * distance / n_len : 0.0f) * n;
    const float4 f =
        sample_composed(ISK_FIELD_ARGS, ISK_COMPOSITION_ARGS, probe);
    c = clamp((iso_values[v] - f.x) / ISK_BULGE_CLEARANCE_WIDTH, 0.0f, 1.0f);
  }
  clearance[v] = c;
}
