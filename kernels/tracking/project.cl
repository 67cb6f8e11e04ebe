// Surface tracking, the projection (Vaillant et al. 2013, section 5, eq. 4):
// each vertex marches back to its rest iso value in the composed field,
// stopping at the 55 degree contact stop, or to the contact surface of the
// part that holds it (the contact by home field). OpenCL C 1.2. CPU
// reference: lib/src/tracking/surface_tracking.cpp (formulas and states
// documented in lib/include/isk/tracking/surface_tracking.hpp). Host class:
// lib/src/cl/surface_tracking.cpp. The includes are resolved from the
// embedded sources; compiled on its own, pass -I kernels.
//
// Every per-vertex array and the one-rings are in the device's vertex order
// (ClSurfaceTracking: the tracked vertices in march order, then the others),
// so the projection reads its vertices in sequence; track_begin gathers the
// skinned positions into it and track_copy_duplicates scatters the results
// back to the mesh's order. Positions are packed float triples
// (vload3/vstore3); one uchar state per vertex (ISK_TRACK_* of abi.h).
// prev_gradients: one float4 per vertex, xyz the unit gradient of the
// vertex's last projection step, w what that step was (ISK_GRADIENT_*).

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
#define ISK_PAIR_CACHE 16
typedef struct {
  uint fields[ISK_PAIR_CACHE];
  float4 samples[ISK_PAIR_CACHE];
  int count, capacity;
  int keep_bounds;
} PairCache;

ISK_INLINE void keep_sample(PairCache* cache, const uint field,
                            const float4 s) {
  if (cache->count < cache->capacity) {
    cache->fields[cache->count] = field;
    cache->samples[cache->count] = s;
    ++cache->count;
  }
}

// Field `field` at x: the kept sample, else sampled.
ISK_INLINE float4 pair_sample(ISK_FIELD_PARAMS, const PairCache* cache,
                              const uint field, const float3 x) {
  for (int n = 0; n < cache->count; ++n)
    if (cache->fields[n] == field) return cache->samples[n];
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
        if (cache->keep_bounds)
          keep_sample(cache, i, (float4)(-bound, 0.0f, 0.0f, 0.0f));
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

// The skinned positions become the working positions, gathered into the
// device's vertex order (source[v]: the mesh vertex at device index v; the
// host keeps the tracked vertices first, in march order); every
// representative with an iso value starts marching. Both position buffers
// get them, so that the launches that skip vertices (active vertices, see
// track_relax) find the others the same in either; no vertex is in reach
// of a contact or crease yet (track_beta_init). With has_start (history-
// dependent tracking), the marching vertices that the last frame stopped
// at a contact or in a crease start from `start` (mesh order) instead.
__kernel void track_begin(const uint vertex_count,
                          __global const float* skinned,
                          __global float* positions,
                          __global const float* iso_values,
                          __global const int* representative,
                          __global uchar* states,
                          __global float4* prev_gradients,
                          __global float4* relax_frames,
                          __global const int* source,
                          __global float* positions_other,
                          __global uchar* reach,
                          __global const float* start,
                          const int has_start, const float history_keep) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  const uchar state = iso_values[v] > 0.0f && representative[v] == (int)v
                          ? ISK_TRACK_MARCHING
                          : ISK_TRACK_UNTRACKED;
  // The last frame's state: a vertex stopped at a contact or in a crease
  // starts from `start`, keeping history_keep of its offset from skinning.
  const uchar last = states[v];
  const float3 s = vload3(source[v], skinned);
  const float3 x = has_start && state == ISK_TRACK_MARCHING &&
                           (last == ISK_TRACK_CONTACT ||
                            last == ISK_TRACK_CREASE)
                       ? s + history_keep * (vload3(source[v], start) - s)
                       : s;
  vstore3(x, v, positions);
  vstore3(x, v, positions_other);
  reach[v] = ISK_REACH_NONE;
  states[v] = state;
  prev_gradients[v] = (float4)(0.0f);
  relax_frames[v] = (float4)(0.0f);
}

// The dislocation guard (isk/tracking/dislocation.hpp; the CPU reference's
// begin): the vertices the host found dislocated by the pose (device
// indices) keep their skinned position (a history start put them
// elsewhere).
__kernel void track_untrack(const uint count, __global const int* vertices,
                            __global uchar* states,
                            __global const float* skinned,
                            __global const int* source,
                            __global float* positions,
                            __global float* positions_other) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const int v = vertices[i];
  states[v] = ISK_TRACK_UNTRACKED;
  const float3 x = vload3(source[v], skinned);
  vstore3(x, v, positions);
  vstore3(x, v, positions_other);
}

// The paper's steps, named as in the CPU reference (surface_tracking.cpp):
// newton_step, contact_stop, march_to_contact; tangential_relaxation is in
// tracking/relax.cl, smoothing_step in tracking/smooth.cl.

// Eq. 4: one step of x towards the surface where the field's value gap
// (iso - f) closes, along the unit gradient, of sigma * gap / |gradient|
// clamped to +-max_step.
ISK_INLINE float3 newton_step(const float3 x, const float3 unit,
                              const float value_gap,
                              const float gradient_length, const float sigma,
                              const float max_step) {
  const float length =
      clamp(sigma * value_gap / gradient_length, -max_step, max_step);
  return x + length * unit;
}

// Section 5, the contact stop: the gradient turned by more than the
// contact angle (cos_contact) since the vertex's last plain step.
ISK_INLINE bool contact_stop(const float3 unit, const float4 prev,
                             const float cos_contact) {
  return prev.w == ISK_GRADIENT_STEP &&
         unit.x * prev.x + unit.y * prev.y + unit.z * prev.z < cos_contact;
}

// The contact march's stop: the contact function's gradient (unit) turned
// back, by more than 90 degrees, since the vertex's last step towards the
// contact surface (frame: that step's c and unit normal). The march passed
// the point nearest to a contact surface it cannot reach (c has a minimum
// above 0 there); Newton steps about that minimum flip direction at every
// step and leave the vertex wherever the frame's last step does, so it
// stops there, at a contact.
ISK_INLINE bool contact_march_stop(const float3 unit, const float prev_kind,
                                   const float4 frame) {
  return prev_kind == ISK_GRADIENT_TO_CONTACT &&
         unit.x * frame.y + unit.y * frame.z + unit.z * frame.w < 0.0f;
}

// The contact by home field: a vertex that another part's field has
// entered (by `entered` over its rest margin, more than contact_entry) up
// to home_floor (h + entered >= its part's surface value less
// contact_home_slack) marches to the contact surface c = entered +
// contact_gap = 0 instead of its iso value, and stops there, or where its
// gradient turns back (contact_march_stop); unless its
// home field h is below home_minimum (its part's surface value less
// contact_home_reach): skinning carried it out of its own part, and it stops
// where it is, converged. ISK_CONTACT_MARCH_NONE: not held, the paper's
// march goes on; ISK_CONTACT_MARCH_STEPPED: x stepped towards the contact
// surface; otherwise the state the vertex stops in.
#define ISK_CONTACT_MARCH_NONE (-1)
#define ISK_CONTACT_MARCH_STEPPED (-2)
ISK_INLINE int march_to_contact(float3* x, float4* prev, float4* frame,
                                const float f, const float iso, const float4 h,
                                const float4 other, const float entered,
                                const float home_floor,
                                const float home_minimum,
                                const float contact_gap, const float tolerance,
                                const float contact_entry, const float sigma,
                                const float max_step,
                                const float min_gradient) {
  bool to_contact = prev->w == ISK_GRADIENT_TO_CONTACT;
  if (to_contact && f < iso - tolerance) {
    to_contact = false;  // left through the surface: the paper's march
    prev->w = ISK_GRADIENT_UNSET;
  }
  if (!(h.x > 0.0f &&
        (to_contact || (f > iso + tolerance && entered > contact_entry &&
                        h.x + entered >= home_floor))))
    return ISK_CONTACT_MARCH_NONE;
  if (!to_contact && !(h.x >= home_minimum)) return ISK_TRACK_CONVERGED;
  const float c = entered + contact_gap;
  if (to_contact && c <= tolerance) return ISK_TRACK_CONTACT;
  const float3 gc = other.yzw - h.yzw;
  const float gc_len = sqrt(gc.x * gc.x + gc.y * gc.y + gc.z * gc.z);
  if (!(gc_len > min_gradient)) return ISK_TRACK_LOST;
  if (contact_march_stop(gc / gc_len, prev->w, *frame))
    return ISK_TRACK_CONTACT;
  prev->w = ISK_GRADIENT_TO_CONTACT;
  *frame = (float4)(c, gc / gc_len);  // the contact surface c = 0
  *x = newton_step(*x, gc / gc_len, -c, gc_len, sigma, max_step);
  return ISK_CONTACT_MARCH_STEPPED;
}

// `steps` projection steps of every marching vertex. step_params: sigma,
// cos(contact angle), tolerance and contact_entry (field units); step_limits per
// vertex (isk::trackingLengths): the largest move and the smallest
// |grad f| (model units); then ISK_TRACKING_PARAMS.
// prev_gradients.w: 0 unset, 1 set, 2 marching to a contact. rest_creases:
// per vertex an index into crease_shifts, -1 none (TrackingMesh::
// rest_crease); crease_shifts: per rest crease pair of the pose, 1 while
// its joints turned by less than rest_crease_degrees (restCreaseShifts).
__kernel void track_project(const uint march_count, __global float* positions,
                            __global const float* iso_values,
                            __global uchar* states,
                            __global float4* prev_gradients, const int steps,
                            const float4 step_params,
                            __global const float2* step_limits,
                            ISK_TRACKING_PARAMS, ISK_FIELD_PARAMS,
                            ISK_COMPOSITION_PARAMS,
                            __global float4* relax_frames,
                            __global float* positions_other,
                            __global const float2* home_floors,
                            __global const int* rest_creases,
                            __global const int* crease_shifts) {
  // Work-item v marches vertex v: the device's order puts the tracked
  // vertices first (march_count of them), by home field and rest locality.
  const uint v = get_global_id(0);
  if (v >= march_count) return;
  uchar state = states[v];
  if (state != ISK_TRACK_MARCHING) return;  // stopped: no more work this frame
  float3 x = vload3(v, positions);
  float4 prev = prev_gradients[v];
  float4 frame = relax_frames[v];
  const float iso = iso_values[v];
  const int home_field = home_fields[v];
  const int home = (contact_flags & ISK_CONTACT_HOME_FIELD) ? home_field : -1;
  const float margin = home >= 0 ? home_margins[v] : 0.0f;
  // The other part's floor and the home field's minimum of the contact march.
  const float2 home_floor = home >= 0 ? home_floors[v] : (float2)(0.0f, 0.0f);
  // On a rest crease whose two joints turned by less than
  // rest_crease_degrees: no march to a contact (the crease shifts).
  const int rest_crease = home >= 0 ? rest_creases[v] : -1;
  const bool crease_shifting = rest_crease >= 0 && crease_shifts[rest_crease];
  // Without the contact by home field the other parts' value is not used.
  const float other_slack = home >= 0 ? margin + step_params.z : INFINITY;
  const float2 limits = step_limits[v];
  const float max_step = limits.x;
  const float min_gradient = limits.y;
  for (int s = 0; s < steps; ++s) {
    float4 h, other;
    // Marching to a contact needs the other parts' exact value.
    const float4 sample = sample_tracking(
        ISK_FIELD_ARGS, ISK_COMPOSITION_ARGS, ISK_TRACKING_ARGS, x, home_field,
        (contact_flags & ISK_CONTACT_VALUE_BOUNDS) && prev.w != ISK_GRADIENT_TO_CONTACT, other_slack, &h, &other);
    const float3 g = sample.yzw;
    const float g_len = sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
    if (!(sample.x > 0.0f) || !(g_len > min_gradient)) {
      state = ISK_TRACK_LOST;
      break;
    }
    float entered = 0.0f;  // how far another part's field exceeds home
    if (home >= 0) {
      entered = other.x - h.x - margin;
      if (crease_shifting && prev.w != ISK_GRADIENT_TO_CONTACT &&
          h.x >= home_floor.y)
        entered = 0.0f;
      const int march = march_to_contact(
          &x, &prev, &frame, sample.x, iso, h, other, entered, home_floor.x,
          home_floor.y,
          contact_gap,
          step_params.z, step_params.w, step_params.x, max_step, min_gradient);
      if (march == ISK_CONTACT_MARCH_STEPPED) continue;
      if (march != ISK_CONTACT_MARCH_NONE) {
        state = (uchar)march;
        break;
      }
    }
    const float3 unit = g / g_len;
    if (contact_stop(unit, prev, step_params.y)) {
      state = ISK_TRACK_CONTACT;
      break;
    }
    prev = (float4)(unit, ISK_GRADIENT_STEP);
    const float d = iso - sample.x;
    if (fabs(d) < step_params.z) {
      // On another part's surface: a crease, smoothed like a contact.
      state = entered > step_params.z ? ISK_TRACK_CREASE : ISK_TRACK_CONVERGED;
      break;
    }
    frame = (float4)(sample.x - iso, unit);
    x = newton_step(x, unit, d, g_len, step_params.x, max_step);
  }
  vstore3(x, v, positions);
  // Stopped: its last move, in the other buffer too (track_relax skips it).
  if (state != ISK_TRACK_MARCHING) vstore3(x, v, positions_other);
  states[v] = state;
  prev_gradients[v] = prev;
  relax_frames[v] = frame;
}
