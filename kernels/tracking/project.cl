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

#include "tracking/sample_tracking.cl"

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
