// evaluate_fields: the composed field (and optionally every field) at a
// list of posed points, the field evaluation of isk::ClFieldEvaluation
// (lib/src/cl/field_evaluation.cpp; CPU reference
// lib/src/fields/field_evaluation.cpp). OpenCL C 1.2.

#include "fields/compose.cl"

// Arguments (ClFieldEvaluation binds them in this order):
//   0 points            packed float3 (x y z per point), model space, posed
//   1 point_count
//   2..6 field data, field params, field count, resolution, field cells
//        (see above)
//   7..12 operator data, pairs, pair count, pair angles, controllers,
//         operator scales (see above)
//   13 out_composed     one float4 per point: value, gradient x y z
//   14 out_per_field    one float4 per point and field, row p * F + i
//   15 write_per_field  0: out_per_field is not touched (may be a dummy)
__kernel void evaluate_fields(__global const float* points,
                              const uint point_count, ISK_FIELD_PARAMS,
                              ISK_COMPOSITION_PARAMS,
                              __global float4* out_composed,
                              __global float4* out_per_field,
                              const uint write_per_field) {
  const uint p = get_global_id(0);
  if (p >= point_count) return;
  const float3 x = vload3(p, points);
  float4 best = (float4)(0.0f);
  for (uint i = 0; i < field_count; ++i) {
    const float4 s =
        sample_field_culled(field_data, field_params, field_cells, i, resolution, x);
    if (write_per_field) out_per_field[(size_t)p * field_count + i] = s;
    best = compose_union(best, s);
  }
  out_composed[p] = compose_pairs(ISK_FIELD_ARGS, ISK_COMPOSITION_ARGS, x, best);
}
