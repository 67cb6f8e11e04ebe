// Surface tracking's sample of the composed field (the tracking broad
// phase): the composed field at a point with the home field's sample and the
// other parts' largest, sampling only the fields of the home field's
// neighbourhood listed in the cell that holds the point. OpenCL C 1.2. CPU
// reference: homeSamples and the neighbourhoods of
// lib/src/tracking/surface_tracking.cpp. Included by tracking/project.cl
// (the march) and tracking/bulge_clearance.cl (the contact bulge's probe),
// both built with the fields' options and the broad phase's
// (ISK_NEIGHBOUR_CELLS, ISK_LANE_TESTS).

#include "fields/compose.cl"

// Cells per axis of each home field's box in the cell lists (the host
// passes its choice for the device: 1, the whole box, or more).
#ifndef ISK_NEIGHBOUR_CELLS
#define ISK_NEIGHBOUR_CELLS 4
#endif

// The contact by home field's data and the tracking broad phase
// (ISK_CONTACT_ARG_COUNT consecutive kernel arguments, bound by
// ClSurfaceTracking::setContactArgs):
// each vertex's home field (-1: none) and rest margin; each field's partners
// at this pose (activePartners: blend pairs turned by less than
// blend_contact_degrees;
// ISK_MAX_PARTNERS per field, -1 padded); the pose's field neighbourhoods
// (fieldNeighbourhoods, split into cells by splitNeighbourhoodsIntoCells:
// per home field h and cell c of its box, in
// neighbour_entries[neighbour_offsets[h * ISK_NEIGHBOUR_CELLS^3 + c] ..
// neighbour_offsets[... + 1]] the fields whose posed support box meets h's
// and that can be non-zero in the cell, ascending, ISK_NEIGHBOUR_PARTNER set
// on h and its partners; in neighbour_pairs[...pair_offsets[h]...] the
// pairs both of whose fields are in h's neighbourhood); contact_gap: the
// contact by home field's gap in field units; contact_flags: the
// ISK_CONTACT_* bits of abi.h (the contact by home field, the
// neighbourhoods, the value bounds of sample_tracking).
#define ISK_TRACKING_PARAMS                                              \
  __global const int *home_fields, __global const float *home_margins,  \
      __global const int *partners, __global const int *neighbour_offsets, \
      __global const int *neighbour_entries,                             \
      __global const int *neighbour_pair_offsets,                        \
      __global const int *neighbour_pairs, const float contact_gap,      \
      const int contact_flags,                                           \
      __global const int *lane_offsets, __global const float8 *lane_params, \
      __global const uchar *lane_masks
#define ISK_TRACKING_ARGS                                                \
  home_fields, home_margins, partners, neighbour_offsets, neighbour_entries, \
      neighbour_pair_offsets, neighbour_pairs, contact_gap, contact_flags, \
      lane_offsets,                                                      \
      lane_params, lane_masks
#ifndef ISK_LANE_TESTS
#define ISK_LANE_TESTS 0
#endif
// ISK_LANE_TESTS=1 (the host's choice on a CPU device): sample_tracking
// tests a cell's listed fields eight at a time. lane_offsets[h] ..
// lane_offsets[h + 1]: home field h's chunks of 8 lanes, its neighbourhood
// (neighbour entries of the whole box, in order) 8 fields per chunk;
// lane_params: ISK_LANE_ROWS float8 per chunk, lane l of row r the
// field's value: rows 0..11 field_params [0..2] (the 3x4 rows), 12..14
// box_min, 15..17 1 / spacing, 18..21 the bounding sphere, 22 the
// neighbour entry and 23 the grid (ints); a padding lane's sphere radius is
// -1. lane_masks: per chunk and cell (chunk-major per home field: byte
// (lane_offsets[h] * cells^3 + cell * chunks + k)) the lanes the cell lists.

// The samples a point's listed fields took, for its blend and bulge pairs
// (sample_tracking): the same values sample_field_culled gives, so that a
// pair composes what it would have sampled again. `capacity` 0: none kept.
// With `keep_bounds` (ISK_CONTACT_PAIR_BOUNDS), a field skipped by its value
// bound is kept as that bound, negated (samples are never negative).
// `complete` while every listed field that passed the sphere and grid tests
// was kept (as its sample, or as its bound): a field not kept is then zero
// at the point (see pair_sample).
#define ISK_PAIR_CACHE 16
typedef struct {
  uint fields[ISK_PAIR_CACHE];
  float4 samples[ISK_PAIR_CACHE];
  int count, capacity;
  int keep_bounds;
  int complete;
} PairCache;

ISK_INLINE void keep_sample(PairCache* cache, const uint field,
                            const float4 s) {
  if (cache->count < cache->capacity) {
    cache->fields[cache->count] = field;
    cache->samples[cache->count] = s;
    ++cache->count;
  } else {
    cache->complete = 0;
  }
}

// Field `field` at x: the kept sample; else 0 where the cache is complete
// (the field is not listed in the point's cell, so it cannot be non-zero
// there, or it failed the sphere or grid test, where sample_field_culled
// gives 0 too); else sampled.
ISK_INLINE float4 pair_sample(ISK_FIELD_PARAMS, const PairCache* cache,
                              const uint field, const float3 x) {
  for (int n = 0; n < cache->count; ++n)
    if (cache->fields[n] == field) return cache->samples[n];
  if (cache->complete) return (float4)(0.0f);
  return sample_field_culled(field_data, field_params, field_cells, field,
                             resolution, x);
}

// One listed field of sample_tracking (below) whose sphere and grid hold
// the point, at node coordinates u in grid `grid` (the home field: its
// sample, home_sample): the cell and bound tests, the sample (kept in
// `cache`), the unions.
ISK_INLINE void take_listed_field(
    ISK_FIELD_DATA_T field_data, __global const float4* field_params,
    __global const uchar* field_cells, const int resolution, const int entry,
    const uint grid, const float3 u, const int home, const float4 home_sample,
    const bool bounded, const float other_limit, float4* best, float4* h,
    float4* other, PairCache* cache) {
  const uint i = (uint)(entry & ISK_NEIGHBOUR_FIELD);
  float4 s = home_sample;
  if ((int)i != home) {
    const uint b = field_cells[cell_index(grid, resolution, u)];
    if (b == 0u) {  // zero at all 8 nodes
      keep_sample(cache, i, (float4)(0.0f));
      return;
    }
    if (bounded && b < 255u) {
      const float bound = (float)b * (1.0f / 255.0f);
      if (bound < fmax(best->x, home_sample.x) &&
          ((entry & ISK_NEIGHBOUR_PARTNER) || bound <= other_limit)) {
        // Not kept, the field may be non-zero: a pair samples it again.
        if (cache->keep_bounds)
          keep_sample(cache, i, (float4)(-bound, 0.0f, 0.0f, 0.0f));
        else
          cache->complete = 0;
        return;  // changes nothing (see sample_tracking)
      }
    }
    __global const float4* p = field_params + ISK_FIELD_PARAM_STRIDE * i;
    const float4 g =
        sample_grid_nodes(field_data, field_params, i, grid, resolution, u);
    s = (float4)(g.x, g.y * p[0].xyz + g.z * p[1].xyz + g.w * p[2].xyz);
  }
  keep_sample(cache, i, s);
  // A zero value changes none of the unions, and the home sample is only
  // used where its value is above 0: skip the bookkeeping (a chain of
  // selects per listed field).
  if (!(s.x > 0.0f)) return;
  *best = compose_union(*best, s);
  if ((int)i == home)
    *h = s;
  else if (!(entry & ISK_NEIGHBOUR_PARTNER))
    *other = compose_union(*other, s);
}

// The composed field at x, plus the home field's sample and the largest
// sample of the other parts' fields (neither the home field nor its
// partners), as homeSamples does on the CPU. `home` is the vertex's home
// field (-1: none): while x lies in its support box only the fields of its
// neighbourhood (boxes that meet it) can be non-zero, so only they are
// sampled, and of those only the ones listed in the cell of h's box that
// holds x (same result, same order, as sampling every field).
//
// With `bounded` (the value bounds of field_cells, isk::cellValueBounds),
// a listed field whose cell bound lies below the larger of the home value
// and the best value so far cannot be the max (it loses to a field already
// met or to the home field, wherever that comes in the list), and if it is
// another part's field and its bound is at most home + other_slack (the
// vertex's margin plus the tolerance), it cannot make the other parts'
// field exceed home by more than the tolerance either, the only test that
// value takes part in outside the march to a contact (where the caller
// passes bounded = false): such a field is not sampled. The result is the
// same as sampling it. With ISK_CONTACT_PAIR_BOUNDS, a blend or bulge pair
// with such a field is composed only where the operator's bound over the
// fields' values (the skipped one's bound for its value) exceeds the
// composed value so far (operator_bound); elsewhere it cannot change it.
ISK_INLINE float4 sample_tracking(ISK_FIELD_PARAMS, ISK_COMPOSITION_PARAMS,
                                  ISK_TRACKING_PARAMS, const float3 x,
                                  const int home, const bool bounded,
                                  const float other_slack, float4* home_out,
                                  float4* other_out) {
  float4 best = (float4)(0.0f);
  float4 h = (float4)(0.0f);
  float4 other = (float4)(0.0f);
  bool listed = false;
  float3 home_u = (float3)(0.0f);
  if (home >= 0 && (contact_flags & ISK_CONTACT_NEIGHBOURHOODS)) {
    home_u = field_node_coords(field_params, (uint)home, x);
    listed = inside_nodes(home_u, resolution);
  }
  if (listed) {
    // The home field first (its node coordinates are known): its value
    // bounds the fields that can matter. It joins the unions at its place
    // in the list.
    const float4 home_sample =
        inside_sphere(field_params, (uint)home, x)
            ? sample_field_at(field_data, field_params, field_cells,
                              (uint)home, resolution, home_u)
            : (float4)(0.0f);
    const float other_limit = home_sample.x + other_slack;
    const int cells = ISK_NEIGHBOUR_CELLS;
    const int3 c = min(convert_int3_rtz(home_u * ((float)cells /
                                                 (float)(resolution - 1))),
                       (int3)(cells - 1));
    const int local_cell = c.x + cells * (c.y + cells * c.z);
    const int pairs_begin = neighbour_pair_offsets[home];
    const int pairs_end = neighbour_pair_offsets[home + 1];
    // Kept only where the neighbourhood has pairs: their fields are listed,
    // and a pair would sample them again.
    PairCache cache;
    cache.count = 0;
    cache.capacity = pairs_end > pairs_begin ? ISK_PAIR_CACHE : 0;
    cache.keep_bounds = contact_flags & ISK_CONTACT_PAIR_BOUNDS;
    cache.complete = 1;
#if ISK_LANE_TESTS
    // The listed fields' sphere and grid tests eight at a time: the home
    // field's neighbourhood in chunks of 8 lanes (lane_params, the list's
    // order), the cell's list a mask of each chunk's lanes (lane_masks).
    const int first_chunk = lane_offsets[home];
    const int chunks = lane_offsets[home + 1] - first_chunk;
    __global const uchar* masks =
        lane_masks + (size_t)first_chunk * (size_t)(cells * cells * cells) +
        (size_t)(local_cell * chunks);
    const float last = (float)(resolution - 1);
    float lane_u[24];
    for (int k = 0; k < chunks; ++k) {
      uint bits = masks[k];
      if (bits == 0u) continue;
      __global const float8* L =
          lane_params + (size_t)(first_chunk + k) * ISK_LANE_ROWS;
      // inside_sphere, field_node_coords and inside_nodes: the same
      // operations in each lane.
      const float8 dx = x.x - L[18], dy = x.y - L[19], dz = x.z - L[20];
      const int8 in_sphere = dx * dx + dy * dy + dz * dz <= L[21];
      const float8 ux =
          (L[0] * x.x + L[1] * x.y + L[2] * x.z + L[3] - L[12]) * L[15];
      const float8 uy =
          (L[4] * x.x + L[5] * x.y + L[6] * x.z + L[7] - L[13]) * L[16];
      const float8 uz =
          (L[8] * x.x + L[9] * x.y + L[10] * x.z + L[11] - L[14]) * L[17];
      const int8 inside = in_sphere & (ux >= 0.0f) & (uy >= 0.0f) &
                          (uz >= 0.0f) & (ux <= last) & (uy <= last) &
                          (uz <= last);
      const int8 m = inside & (int8)(1, 2, 4, 8, 16, 32, 64, 128);
      const int4 m4 = m.lo + m.hi;
      const int2 m2 = m4.lo + m4.hi;
      bits &= (uint)(m2.x + m2.y);
      vstore8(ux, 0, lane_u);
      vstore8(uy, 0, lane_u + 8);
      vstore8(uz, 0, lane_u + 16);
      __global const int* lane_entries = (__global const int*)(L + 22);
      __global const int* lane_grids = (__global const int*)(L + 23);
      while (bits != 0u) {  // the lanes left, lowest first
        const uint lane = 31u - clz(bits & (0u - bits));
        bits &= bits - 1u;
        take_listed_field(
            field_data, field_params, field_cells, resolution,
            lane_entries[lane], (uint)lane_grids[lane],
            (float3)(lane_u[lane], lane_u[8 + lane], lane_u[16 + lane]), home,
            home_sample, bounded, other_limit, &best, &h, &other, &cache);
      }
    }
#else
    const int cell = home * cells * cells * cells + local_cell;
    const int end = neighbour_offsets[cell + 1];
    for (int n = neighbour_offsets[cell]; n < end; ++n) {
      const int entry = neighbour_entries[n];
      const uint i = (uint)(entry & ISK_NEIGHBOUR_FIELD);
      if (!inside_sphere(field_params, i, x)) continue;
      float3 u = home_u;
      uint grid = 0u;
      if ((int)i != home) {
        u = field_node_coords(field_params, i, x);
        if (!inside_nodes(u, resolution)) continue;
        grid = (uint)field_params[ISK_FIELD_PARAM_STRIDE * i + 3].w;
      }
      take_listed_field(field_data, field_params, field_cells, resolution,
                        entry, grid, u, home, home_sample, bounded,
                        other_limit, &best, &h, &other, &cache);
    }
#endif
    // compose_one_pair's work with the samples the list took.
    for (int n = pairs_begin; n < pairs_end; ++n) {
      const uint k = (uint)neighbour_pairs[n];
      if (!(k < pair_count)) continue;
      const int4 pair = pairs[k];
      float4 a = pair_sample(ISK_FIELD_ARGS, &cache, (uint)pair.x, x);
      if (!(a.x > 0.0f) && !(a.x < 0.0f)) continue;
      float4 b = pair_sample(ISK_FIELD_ARGS, &cache, (uint)pair.y, x);
      if (!(b.x > 0.0f) && !(b.x < 0.0f)) continue;
      if (a.x < 0.0f || b.x < 0.0f) {
        // A field the list skipped by its value bound (kept negated): the
        // pair cannot raise the composed value where the operator's bound
        // over the two values or bounds does not exceed it (compose_union
        // keeps `best` on a tie; 1e-6 covers the trilinear interpolation's
        // rounding above its largest node). Else the field is sampled, as
        // pair_sample would have.
        const float ba = fabs(a.x), bb = fabs(b.x);
        if (operator_bound(operator_data, pair.z, operator_scales,
                           fmax(ba, bb), fmin(ba, bb)) + 1e-6f <= best.x)
          continue;
        if (a.x < 0.0f)
          a = sample_field_culled(field_data, field_params, field_cells,
                                  (uint)pair.x, resolution, x);
        if (!(a.x > 0.0f)) continue;
        if (b.x < 0.0f)
          b = sample_field_culled(field_data, field_params, field_cells,
                                  (uint)pair.y, resolution, x);
        if (!(b.x > 0.0f)) continue;
      }
      best = compose_union(best,
                           compose_pair(ISK_COMPOSITION_ARGS, k, a, b));
    }
    *home_out = h;
    *other_out = other;
    return best;
  }
  for (uint i = 0; i < field_count; ++i) {
    const float4 s = sample_field_culled(field_data, field_params, field_cells,
                                         i, resolution, x);
    if (!(s.x > 0.0f)) continue;  // changes nothing (see above)
    best = compose_union(best, s);
    if (home < 0) continue;
    if ((int)i == home) {
      h = s;
      continue;
    }
    bool partner = false;
    for (int k = 0; k < ISK_MAX_PARTNERS; ++k)
      partner = partner || partners[home * ISK_MAX_PARTNERS + k] == (int)i;
    if (!partner) other = compose_union(other, s);
  }
  *home_out = h;
  *other_out = other;
  return compose_pairs(ISK_FIELD_ARGS, ISK_COMPOSITION_ARGS, x, best);
}
