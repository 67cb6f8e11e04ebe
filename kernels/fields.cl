// Baked implicit fields (isk/fields/field_grid.hpp) evaluated at posed points, and
// their composition (isk/fields/field_composition.hpp: the max of every field and of
// every blend or bulge pair, eq. 3). OpenCL C 1.2; includes abi.h. CPU
// reference: lib/src/fields/field_grid.cpp (sampling), lib/src/fields/field_evaluation.cpp
// (transforms, broad phase, composition), lib/src/fields/composition_operator.cpp
// (operator tables, controllers) and lib/src/fields/field_composition.cpp
// (composePair). Host class: lib/src/cl/field_evaluation.cpp.
//
// Storage, chosen at build time by ISK_FIELDS_IMAGE (0 when undefined):
//   1: one read-only image3d_t atlas, CL_RGBA / CL_FLOAT, every grid one
//      N^3 tile of it (tiles side by side in x, y and z; grid g at tile
//      (g % tx, (g / tx) % ty, g / (tx * ty))); the 8 texels around
//      tile_origin + u are read unfiltered and interpolated here, in the
//      buffer's order: hardware filtering is not used because GPUs weight
//      with 8-bit fractions (NVIDIA: value errors near 1e-3, gradients 5%),
//      too coarse to march back to an iso value;
//   0: a __global const float4* buffer, grid g at offset g * N^3, node
//      (x, y, z) at x + N * (y + N * z), interpolated trilinearly here exactly
//      as FieldGrid::sampleLocal does it. With ISK_FIELDS_HALF=1 (grids
//      rounded to half precision, isk::roundGridsToHalf) the buffer holds
//      4 halves per node instead, same layout, read by vload_half4 (exact)
//      and interpolated in float as the reference does.
// A node's float4 is (value, gradient x y z), gradient in the bone frame.
// Field i samples grid i, except in a crowd (below, param [3].w).
// field_cells: per grid (N-1)^3 bytes, one per grid cell, cell (i, j, k)
// at i + (N - 1) * (j + (N - 1) * k) (isk::cellValueBounds): 0 when the
// cell's 8 nodes are all zero, so that a sample there is zero without
// loading them; else b, every value interpolated in the cell below b / 255
// (255: no bound), which lets the tracking skip fields that cannot matter.
//
// Field parameters: ISK_FIELD_PARAM_STRIDE float4 per field,
//   [0..2] rows of the model -> bone 3x4 matrix (per pose);
//   [3]    box_min.xyz (bone frame), w the index of the field's grid in
//          the field data and the occupied cells (as a float): the field's
//          own index, or, in a crowd of instances (isk::ImplicitCrowd), the
//          grid the instances share;
//   [4]    1 / spacing, xyz, w = N - 1 (last node index, as a float);
//   [5]    image path: tile origin + 0.5 (texels), xyz (the texel index is
//          its integer part); unused by the buffer;
//   [6]    bounding sphere of the support box, model space (per pose):
//          centre xyz, w = squared radius. A point outside it is outside the
//          box: the field is not sampled (broad phase).
//
// Operator tables (isk/fields/composition_operator.hpp), same storage as the fields:
// T tables of N^3 float4 (G, dG/dx, dG/dy, 0) over (x, y, theta), x the
// larger field; node (i, j, k) of table t at i + N * (j + N * (k + N * t))
// (the buffer) or at texel (i, j, t * N + k) (the image, N x N x T*N).
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

// The reference interpolates without fused multiply-adds; so does the buffer
// path, so that on a CPU device both agree to the last bits.
#pragma OPENCL FP_CONTRACT OFF

#include "abi.h"

#ifndef ISK_FIELDS_IMAGE
#define ISK_FIELDS_IMAGE 0
#endif

// The per-sample helpers are inlined into their callers: on a CPU device
// (PoCL) a call per field sample keeps the grid loads of consecutive fields
// from overlapping.
#define ISK_INLINE inline __attribute__((always_inline))


// The trilinear interpolation of a cell's 8 corner values (cXYZ at
// x, y, z in {0, 1}) at t in [0, 1]^3: along x, then y, then z, in the CPU
// reference's order (detail::trilinearNodes, lib/src/fields/trilinear.hpp).
ISK_INLINE float4 trilinear_corners(const float4 c000, const float4 c100,
                                    const float4 c010, const float4 c110,
                                    const float4 c001, const float4 c101,
                                    const float4 c011, const float4 c111,
                                    const float3 t) {
  const float4 x00 = c000 + t.x * (c100 - c000);
  const float4 x10 = c010 + t.x * (c110 - c010);
  const float4 x01 = c001 + t.x * (c101 - c001);
  const float4 x11 = c011 + t.x * (c111 - c011);
  const float4 y0 = x00 + t.y * (x10 - x00);
  const float4 y1 = x01 + t.y * (x11 - x01);
  return y0 + t.z * (y1 - y0);
}

#if ISK_FIELDS_IMAGE
#define ISK_FIELD_DATA_T read_only image3d_t
#define ISK_OPERATOR_DATA_T read_only image3d_t
__constant sampler_t kTexelSampler =
    CLK_NORMALIZED_COORDS_FALSE | CLK_ADDRESS_CLAMP_TO_EDGE | CLK_FILTER_NEAREST;

// Trilinear interpolation of the n^3 tile whose node (0, 0, 0) is texel
// `origin`, at node coordinates u in [0, n - 1]: the same order of
// operations as trilinear_nodes (the buffer path) and the CPU reference.
ISK_INLINE float4 trilinear_texels(read_only image3d_t image, const int4 origin,
                                   const int n, const float3 u) {
  const int3 i = min(convert_int3_rtz(u), (int3)(n - 2));
  const float3 t = u - convert_float3(i);
  const int4 b = origin + (int4)(i, 0);
  const float4 c000 = read_imagef(image, kTexelSampler, b);
  const float4 c100 = read_imagef(image, kTexelSampler, b + (int4)(1, 0, 0, 0));
  const float4 c010 = read_imagef(image, kTexelSampler, b + (int4)(0, 1, 0, 0));
  const float4 c110 = read_imagef(image, kTexelSampler, b + (int4)(1, 1, 0, 0));
  const float4 c001 = read_imagef(image, kTexelSampler, b + (int4)(0, 0, 1, 0));
  const float4 c101 = read_imagef(image, kTexelSampler, b + (int4)(1, 0, 1, 0));
  const float4 c011 = read_imagef(image, kTexelSampler, b + (int4)(0, 1, 1, 0));
  const float4 c111 = read_imagef(image, kTexelSampler, b + (int4)(1, 1, 1, 0));
  return trilinear_corners(c000, c100, c010, c110, c001, c101, c011, c111, t);
}
#else
#ifndef ISK_FIELDS_HALF
#define ISK_FIELDS_HALF 0
#endif
#if ISK_FIELDS_HALF
#define ISK_FIELD_DATA_T __global const half*
#else
#define ISK_FIELD_DATA_T __global const float4*
#endif
#define ISK_OPERATOR_DATA_T __global const float4*
#endif

#define ISK_FIELD_PARAMS                                            \
  ISK_FIELD_DATA_T field_data, __global const float4 *field_params, \
      const uint field_count, const int resolution,                 \
      __global const uchar *field_cells
#define ISK_FIELD_ARGS \
  field_data, field_params, field_count, resolution, field_cells
#define ISK_COMPOSITION_PARAMS                                              \
  ISK_OPERATOR_DATA_T operator_data, __global const int4 *pairs,            \
      const uint pair_count, __global const float *pair_angles,             \
      __global const float *controllers, const float4 operator_scales
#define ISK_COMPOSITION_ARGS                                          \
  operator_data, pairs, pair_count, pair_angles, controllers, \
      operator_scales

#if !ISK_FIELDS_IMAGE
// Trilinear interpolation of the float4 nodes of an n^3 grid at node
// coordinates u in [0, n - 1]; `grid` points at its node (0, 0, 0). Same
// order of operations as detail::trilinearNodes (lib/src/fields/trilinear.hpp).
ISK_INLINE float4 trilinear_nodes(__global const float4* grid, const int n,
                       const float3 u) {
  const int3 i = min(convert_int3_rtz(u), (int3)(n - 2));
  const float3 t = u - convert_float3(i);
  const size_t dy = (size_t)n;
  const size_t dz = (size_t)n * (size_t)n;
  __global const float4* b =
      grid + ((size_t)i.x + dy * (size_t)i.y + dz * (size_t)i.z);
  return trilinear_corners(b[0], b[1], b[dy], b[dy + 1], b[dz], b[dz + 1],
                           b[dy + dz], b[dy + dz + 1], t);
}

#if ISK_FIELDS_HALF
// trilinear_nodes over a grid of halves (4 per node); `first` is the index,
// in nodes, of its node (0, 0, 0).
ISK_INLINE float4 trilinear_half_nodes(__global const half* data,
                                       const size_t first, const int n,
                                       const float3 u) {
  const int3 i = min(convert_int3_rtz(u), (int3)(n - 2));
  const float3 t = u - convert_float3(i);
  const size_t dy = (size_t)n;
  const size_t dz = (size_t)n * (size_t)n;
  const size_t b =
      first + ((size_t)i.x + dy * (size_t)i.y + dz * (size_t)i.z);
  const float4 c000 = vload_half4(b, data);
  const float4 c100 = vload_half4(b + 1, data);
  const float4 c010 = vload_half4(b + dy, data);
  const float4 c110 = vload_half4(b + dy + 1, data);
  const float4 c001 = vload_half4(b + dz, data);
  const float4 c101 = vload_half4(b + dz + 1, data);
  const float4 c011 = vload_half4(b + dy + dz, data);
  const float4 c111 = vload_half4(b + dy + dz + 1, data);
  return trilinear_corners(c000, c100, c010, c110, c001, c101, c011, c111, t);
}
#endif
#endif

// Whether node coordinates u lie in the grid (its support box).
ISK_INLINE bool inside_nodes(const float3 u, const int resolution) {
  const float last = (float)(resolution - 1);
  return u.x >= 0.0f && u.y >= 0.0f && u.z >= 0.0f && u.x <= last &&
         u.y <= last && u.z <= last;
}

// Index in field_cells of the cell holding node coordinates u (inside the
// grid) of grid `grid`.
ISK_INLINE uint cell_index(const uint grid, const int resolution,
                           const float3 u) {
  const uint cells = (uint)(resolution - 1);
  const int3 c = min(convert_int3_rtz(u), (int3)(resolution - 2));
  return grid * cells * cells * cells + (uint)c.x +
         cells * ((uint)c.y + cells * (uint)c.z);
}

// The trilinear sample of grid `grid` (field `field`'s) at node coordinates
// u inside it, loads and all.
ISK_INLINE float4 sample_grid_nodes(ISK_FIELD_DATA_T field_data,
                                    __global const float4* params,
                                    const uint field, const uint grid,
                                    const int resolution, const float3 u) {
#if ISK_FIELDS_IMAGE
  const float3 origin = params[ISK_FIELD_PARAM_STRIDE * field + 5].xyz;
  return trilinear_texels(field_data, (int4)(convert_int3_rtz(origin), 0),
                          resolution, u);
#else
  const size_t n = (size_t)resolution;
#if ISK_FIELDS_HALF
  return trilinear_half_nodes(field_data, (size_t)grid * n * n * n,
                              resolution, u);
#else
  return trilinear_nodes(field_data + (size_t)grid * n * n * n, resolution,
                         u);
#endif
#endif
}

// Value and bone-frame gradient of field `field` at node coordinates u
// (bone-frame point minus box_min, over the spacing). 0 outside [0, N-1].
ISK_INLINE float4 sample_field_nodes(ISK_FIELD_DATA_T field_data,
                                     __global const float4* params,
                                     __global const uchar* field_cells,
                                     const uint field, const int resolution,
                                     const float3 u) {
  if (!inside_nodes(u, resolution)) return (float4)(0.0f);
  // A cell whose 8 nodes are all zero interpolates to zero: its grid
  // loads are skipped (most of a support box lies outside the field's
  // support).
  const uint grid = (uint)params[ISK_FIELD_PARAM_STRIDE * field + 3].w;
  if (field_cells[cell_index(grid, resolution, u)] == 0) return (float4)(0.0f);
  return sample_grid_nodes(field_data, params, field, grid, resolution, u);
}


// Node coordinates of model-space point x (posed) in field `field`'s grid:
// x is taken to the bone frame by the field's 3x4 rows.
ISK_INLINE float3 field_node_coords(__global const float4* field_params,
                         const uint field, const float3 x) {
  __global const float4* p = field_params + ISK_FIELD_PARAM_STRIDE * field;
  const float4 r0 = p[0];
  const float4 r1 = p[1];
  const float4 r2 = p[2];
  // Column by column, as the reference's Eigen product sums.
  const float3 bone =
      (float3)(r0.x, r1.x, r2.x) * x.x + (float3)(r0.y, r1.y, r2.y) * x.y +
      (float3)(r0.z, r1.z, r2.z) * x.z + (float3)(r0.w, r1.w, r2.w);
  return (bone - p[3].xyz) * p[4].xyz;
}

// Value and model-space gradient of field `field` at node coordinates u:
// the gradient comes back by the transpose of the rows' linear part.
ISK_INLINE float4 sample_field_at(ISK_FIELD_DATA_T field_data,
                                  __global const float4* field_params,
                                  __global const uchar* field_cells,
                                  const uint field, const int resolution,
                                  const float3 u) {
  __global const float4* p = field_params + ISK_FIELD_PARAM_STRIDE * field;
  const float4 s = sample_field_nodes(field_data, field_params, field_cells,
                                      field, resolution, u);
  const float3 g = s.y * p[0].xyz + s.z * p[1].xyz + s.w * p[2].xyz;
  return (float4)(s.x, g);
}

// Value and model-space gradient of field `field` at model-space point x
// (posed).
ISK_INLINE float4 sample_field(ISK_FIELD_DATA_T field_data,
                               __global const float4* field_params,
                               __global const uchar* field_cells,
                               const uint field, const int resolution,
                               const float3 x) {
  return sample_field_at(field_data, field_params, field_cells, field,
                         resolution, field_node_coords(field_params, field, x));
}

// The field `field` at x if x lies in its bounding sphere, else 0 (value and
// gradient): the broad phase.
ISK_INLINE bool inside_sphere(__global const float4* field_params, const uint field,
                   const float3 x) {
  const float4 sphere = field_params[ISK_FIELD_PARAM_STRIDE * field + 6];
  const float3 d = x - sphere.xyz;
  return d.x * d.x + d.y * d.y + d.z * d.z <= sphere.w;
}

ISK_INLINE float4 sample_field_culled(ISK_FIELD_DATA_T field_data,
                                      __global const float4* field_params,
                                      __global const uchar* field_cells,
                                      const uint field, const int resolution,
                                      const float3 x) {
  if (!inside_sphere(field_params, field, x)) return (float4)(0.0f);
  return sample_field(field_data, field_params, field_cells, field, resolution,
                      x);
}

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
