// The composition of the bones' fields into the skin's field (paper section
// 4.2, eq. 3; isk/fields/field_composition.hpp): the max of every field and
// of every blend or bulge pair, through the operator tables. OpenCL C 1.2.
// CPU reference: lib/src/fields/composition_operator.cpp (operator tables,
// controllers) and lib/src/fields/field_composition.cpp (composePair). Host
// class: lib/src/cl/field_evaluation.cpp. Included by fields/evaluate.cl and
// tracking/project.cl.
//
// Operator tables (isk/fields/composition_operator.hpp), same storage as the fields:
// T tables of N^3 float4 (G, dG/dx, dG/dy, w) over (x, y, theta), x the
// larger field; node (i, j, k) of table t at i + N * (j + N * (k + N * t))
// (the buffer) or at texel (i, j, t * N + k) (the image, N x N x T*N). w is
// 0 but at the nodes (i, j, 0), where the host writes G's bound up to them
// (operator_bound).
// Composition parameters (six consecutive kernel arguments,
// ISK_COMPOSITION_PARAMS, bound by ClFieldEvaluation::setCompositionArgs):
//   operator_data    the tables;
//   pairs            int4 per blend or bulge pair: field a, field b, table,
//                    offset of its controller in `controllers`;
//   pair_count;
//   pair_angles      float per pair (per pose): its joint's rotation from
//                    the bind pose, the cap of alpha (pairJointAngles);
//   controllers      ISK_CONTROLLER_SAMPLES floats each: theta at
//                    alpha = pi * i / (ISK_CONTROLLER_SAMPLES - 1);
//   operator_scales  N - 1, (N - 1) / (pi / 4) (theta -> node), and
//                    (ISK_CONTROLLER_SAMPLES - 1) / pi (alpha -> sample), as
//                    the host computes them in float.
//
// Later kernels sample the same data: declare ISK_FIELD_PARAMS and
// ISK_COMPOSITION_PARAMS among their parameters (field data, field params,
// field count, resolution, field cells: five consecutive kernel arguments
// bound by ClFieldEvaluation::setFieldArgs; then the six above) and call
// sample_composed(ISK_FIELD_ARGS, ISK_COMPOSITION_ARGS, x).

#include "fields/sample.cl"

#define ISK_COMPOSITION_PARAMS                                              \
  ISK_OPERATOR_DATA_T operator_data, __global const int4 *pairs,            \
      const uint pair_count, __global const float *pair_angles,             \
      __global const float *controllers, const float4 operator_scales
#define ISK_COMPOSITION_ARGS                                          \
  operator_data, pairs, pair_count, pair_angles, controllers, \
      operator_scales

// Union (Vaillant et al. 2013, eq. 3): the larger value with its gradient;
// on ties the one met first stays. Start from (float4)(0): nothing
// positive gives value 0 and a zero gradient.
ISK_INLINE float4 compose_union(const float4 best, const float4 sample) {
  return sample.x > best.x ? sample : best;
}

// Table `table` at (x, y, theta), x >= y: G, dG/dx, dG/dy. The buffer path
// interpolates as OperatorTable::sample does.
float3 sample_operator(ISK_OPERATOR_DATA_T operator_data, const int table,
                       const float4 scales, const float x, const float y,
                       const float theta) {
  const float last = scales.x;
  const float3 u = (float3)(clamp(x, 0.0f, 1.0f) * last,
                            clamp(y, 0.0f, 1.0f) * last,
                            clamp(theta * scales.y, 0.0f, last));
#if ISK_FIELDS_IMAGE
  const int n = (int)last + 1;
  return trilinear_texels(operator_data, (int4)(0, 0, table * n, 0), n, u).xyz;
#else
  const int n = (int)last + 1;
  const size_t nn = (size_t)n;
  return trilinear_nodes(operator_data + (size_t)table * nn * nn * nn, n, u)
      .xyz;
#endif
}

// An upper bound of table `table`'s G over x <= x_max, y <= y_max (x the
// larger field) and every theta: node (i, j, 0)'s fourth component, the
// largest G of the nodes up to (i, j) (written at upload,
// field_evaluation.cpp), i and j past the last node trilinear interpolation
// can weigh.
float operator_bound(ISK_OPERATOR_DATA_T operator_data, const int table,
                     const float4 scales, const float x_max,
                     const float y_max) {
  const float last = scales.x;
  const int n = (int)last + 1;
  const int i = min((int)(clamp(x_max, 0.0f, 1.0f) * last) + 1, n - 1);
  const int j = min((int)(clamp(y_max, 0.0f, 1.0f) * last) + 1, n - 1);
#if ISK_FIELDS_IMAGE
  return read_imagef(operator_data, kTexelSampler, (int4)(i, j, table * n, 0))
      .w;
#else
  const size_t nn = (size_t)n;
  return operator_data[(size_t)table * nn * nn * nn + (size_t)i + nn * (size_t)j]
      .w;
#endif
}

// A blend or bulge pair's composition of samples a and b (value, gradient):
// theta from the angle between the gradients through the pair's
// controller (alpha capped by the pair's joint angle), then the table, then
// the chain rule (composePair).
float4 compose_pair(ISK_COMPOSITION_PARAMS, const uint k, const float4 a,
                    const float4 b) {
  const int4 pair = pairs[k];
  const float3 ga = a.yzw;
  const float3 gb = b.yzw;
  const float la = sqrt(ga.x * ga.x + ga.y * ga.y + ga.z * ga.z);
  const float lb = sqrt(gb.x * gb.x + gb.y * gb.y + gb.z * gb.z);
  float alpha = 0.0f;
  if (la > 0.0f && lb > 0.0f)
    alpha = acos(clamp((ga.x * gb.x + ga.y * gb.y + ga.z * gb.z) / (la * lb),
                       -1.0f, 1.0f));
  alpha = min(alpha, pair_angles[k]);
  __global const float* c = controllers + pair.w;
  const float s = clamp(alpha * operator_scales.z, 0.0f,
                        (float)(ISK_CONTROLLER_SAMPLES - 1));
  const int i = min((int)s, ISK_CONTROLLER_SAMPLES - 2);
  const float theta = c[i] + (s - (float)i) * (c[i + 1] - c[i]);
  const int first = a.x >= b.x;
  const float3 g = sample_operator(operator_data, pair.z, operator_scales,
                                   first ? a.x : b.x, first ? b.x : a.x, theta);
  const float d1 = first ? g.y : g.z;
  const float d2 = first ? g.z : g.y;
  return (float4)(g.x, d1 * ga + d2 * gb);
}

// Pair k on top of `best` (the max of the fields so far).
float4 compose_one_pair(ISK_FIELD_PARAMS, ISK_COMPOSITION_PARAMS,
                        const float3 x, const uint k, const float4 best) {
  const int4 pair = pairs[k];
  const float4 a = sample_field_culled(field_data, field_params, field_cells, (uint)pair.x,
                                       resolution, x);
  if (!(a.x > 0.0f)) return best;  // the pair is max(a, b): already in
  const float4 b = sample_field_culled(field_data, field_params, field_cells, (uint)pair.y,
                                       resolution, x);
  if (!(b.x > 0.0f)) return best;
  return compose_union(best, compose_pair(ISK_COMPOSITION_ARGS, k, a, b));
}

// The blend and bulge pairs on top of `best` (the max of every field).
float4 compose_pairs(ISK_FIELD_PARAMS, ISK_COMPOSITION_PARAMS,
                     const float3 x, float4 best) {
  for (uint k = 0; k < pair_count; ++k)
    best = compose_one_pair(ISK_FIELD_ARGS, ISK_COMPOSITION_ARGS, x, k, best);
  return best;
}

// The composed field at model-space point x.
float4 sample_composed(ISK_FIELD_PARAMS, ISK_COMPOSITION_PARAMS,
                       const float3 x) {
  float4 best = (float4)(0.0f);
  for (uint i = 0; i < field_count; ++i)
    best = compose_union(best, sample_field_culled(field_data, field_params, field_cells, i,
                                                   resolution, x));
  return compose_pairs(ISK_FIELD_ARGS, ISK_COMPOSITION_ARGS, x, best);
}
