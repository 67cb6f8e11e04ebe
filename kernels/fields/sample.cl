// The baked implicit fields of the bones (paper section 4.1, isk/fields/
// field_grid.hpp): their storage on the device and their sampling at posed
// points, with the broad phase of each field's bounding sphere. OpenCL C
// 1.2. CPU reference: lib/src/fields/field_grid.cpp (sampling) and
// lib/src/fields/field_evaluation.cpp (transforms, broad phase). Included by
// fields/compose.cl.
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

#include "common.h"

#ifndef ISK_FIELDS_IMAGE
#define ISK_FIELDS_IMAGE 0
#endif

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
