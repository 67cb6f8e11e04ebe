// The kernels' ABI: every constant, flag and argument index that the host
// (lib/src/cl/) and the kernels (kernels/*.cl) must agree on, defined once.
// Plain preprocessor definitions, so that this one file is valid C++ and
// OpenCL C 1.2: the kernels include it (`#include "abi.h"`, resolved from
// the embedded sources), the host includes it from lib/src/cl/ and checks
// the public enums (TrackState, RelaxationRule, RingKind) against it at
// compile time (lib/src/cl/abi_checks.hpp).
#ifndef ISK_KERNELS_ABI_H
#define ISK_KERNELS_ABI_H

// --- Tracking states: one uchar per vertex (isk::TrackState) -------------
#define ISK_TRACK_MARCHING 0
#define ISK_TRACK_CONVERGED 1
#define ISK_TRACK_CONTACT 2
#define ISK_TRACK_LOST 3
#define ISK_TRACK_UNTRACKED 4
#define ISK_TRACK_CREASE 5

// --- One-rings and relaxation rules (isk::RingKind, isk::RelaxationRule) -
#define ISK_RING_CLOSED 0
#define ISK_RULE_FIXED 3

// --- The last projection step of a vertex: prev_gradients[v].w -----------
// Unset (no step yet, or reset after leaving a contact), a plain step, or a
// step that entered another part's surface (the march to contact).
#define ISK_GRADIENT_UNSET 0.0f
#define ISK_GRADIENT_STEP 1.0f
#define ISK_GRADIENT_TO_CONTACT 2.0f

// --- Contact by home field and the broad phase ----------------------------
// Partners per field (activePartners), -1 padded.
#define ISK_MAX_PARTNERS 8
// A neighbourhood entry: the field index, ISK_NEIGHBOUR_PARTNER set when the
// field is the home field or one of its partners.
#define ISK_NEIGHBOUR_PARTNER 0x10000
#define ISK_NEIGHBOUR_FIELD 0xffff
// contact_flags, a bit set: the contact by home field on (off: the paper's
// march only), the field neighbourhoods used (off: every field is sampled),
// fields skipped by their value bounds, blend and bulge pairs skipped by
// their operator's bound over those value bounds.
#define ISK_CONTACT_HOME_FIELD 1
#define ISK_CONTACT_NEIGHBOURHOODS 2
#define ISK_CONTACT_VALUE_BOUNDS 4
#define ISK_CONTACT_PAIR_BOUNDS 8

// --- Volume restoration (tracking/restore_volume.cl) ----------------------
// The most triangles or vertices of one group a work-item sums.
#define ISK_VOLUME_CHUNK 256
// The largest fraction of its inward move given back to a vertex near
// another connected component of the welded mesh
// (TrackingMesh::VolumeGroups::near_other), whatever volume_restore is: 1,
// back to its skinned position at most (pushed out past it there, the skin
// presses into the other piece).
#define ISK_VOLUME_NEAR_LIMIT 1.0f
// The contact bulge's clearance ramp (field units): a band vertex's push
// fades from full to none as the composed field at its probe rises from
// this far below its iso value to it (contactBulgeClearance).
#define ISK_BULGE_CLEARANCE_WIDTH 0.05f
// Lane tests on a CPU device: fields tested eight at a time, each chunk
// ISK_LANE_ROWS rows of ISK_LANE_WIDTH floats.
#define ISK_LANE_WIDTH 8
#define ISK_LANE_ROWS 24

// The fold guard's ramp: a triangle's fold weight grows from 0 to 1 as the
// cosines of its three tests pass their threshold by this much
// (tracking/fold_guard.cl, CpuSurfaceTracking::weighFolds).
#define ISK_FOLD_RAMP 0.1f

// The crease gate's ramps (tracking/smooth.cl, CpuSurfaceTracking::smooth):
// a crease vertex's source value is 1 where its ring's vector area fell to
// ISK_CREASE_AREA_FULL of its skinned area, its near centroid shifted by
// ISK_CREASE_SHIFT_FULL of the mean near rest length, or a spoke stretched
// by ISK_CREASE_STRETCH_FULL of its rest length beyond its skinned length;
// 0 above ISK_CREASE_AREA_NONE and below ISK_CREASE_SHIFT_NONE and
// ISK_CREASE_STRETCH_NONE; linear between.
#define ISK_CREASE_AREA_FULL 0.4f
#define ISK_CREASE_AREA_NONE 0.8f
#define ISK_CREASE_SHIFT_NONE 0.2f
#define ISK_CREASE_SHIFT_FULL 0.5f
#define ISK_CREASE_STRETCH_NONE 0.1f
#define ISK_CREASE_STRETCH_FULL 0.3f

// --- Active vertices: reach[v], the first diffusion step that may change v
#define ISK_REACH_NONE 255
#define ISK_REACH_MAX 254

// --- Fields and operators --------------------------------------------------
// float4 per field in field_params (fields/sample.cl's layout).
#define ISK_FIELD_PARAM_STRIDE 7
// Samples of each theta controller over alpha in [0, pi].
#define ISK_CONTROLLER_SAMPLES 65

// --- Kernel argument blocks -------------------------------------------------
// Consecutive arguments bound by one host call: the field data
// (ClFieldEvaluation::setFieldArgs: data, params, count, resolution, cells),
// the composition (setCompositionArgs: operator data, pairs, pair count,
// pair angles, controllers, operator scales) and the contact data
// (ClSurfaceTracking::setContactArgs: ISK_TRACKING_PARAMS).
#define ISK_FIELD_ARG_COUNT 5
#define ISK_FIELD_ARG_CELLS 4  // within the field block
#define ISK_COMPOSITION_ARG_COUNT 6
#define ISK_CONTACT_ARG_COUNT 12

// evaluate_fields's arguments (fields/evaluate.cl).
#define ISK_EVALUATE_ARG_FIELDS 2
#define ISK_EVALUATE_ARG_COMPOSITION \
  (ISK_EVALUATE_ARG_FIELDS + ISK_FIELD_ARG_COUNT)
#define ISK_EVALUATE_ARG_OUTPUTS \
  (ISK_EVALUATE_ARG_COMPOSITION + ISK_COMPOSITION_ARG_COUNT)

// track_project's arguments (tracking/project.cl).
#define ISK_PROJECT_ARG_CONTACT 8
#define ISK_PROJECT_ARG_FIELDS (ISK_PROJECT_ARG_CONTACT + ISK_CONTACT_ARG_COUNT)
#define ISK_PROJECT_ARG_COMPOSITION \
  (ISK_PROJECT_ARG_FIELDS + ISK_FIELD_ARG_COUNT)
#define ISK_PROJECT_ARG_RELAX_FRAMES \
  (ISK_PROJECT_ARG_COMPOSITION + ISK_COMPOSITION_ARG_COUNT)
#define ISK_PROJECT_ARG_OTHER_POSITIONS (ISK_PROJECT_ARG_RELAX_FRAMES + 1)
#define ISK_PROJECT_ARG_HOME_FLOORS (ISK_PROJECT_ARG_OTHER_POSITIONS + 1)
#define ISK_PROJECT_ARG_REST_CREASES (ISK_PROJECT_ARG_HOME_FLOORS + 1)
#define ISK_PROJECT_ARG_CREASE_SHIFTS (ISK_PROJECT_ARG_REST_CREASES + 1)

// track_bulge_clearance's arguments (tracking/bulge_clearance.cl).
#define ISK_BULGE_CLEARANCE_ARG_CONTACT 13
#define ISK_BULGE_CLEARANCE_ARG_FIELDS \
  (ISK_BULGE_CLEARANCE_ARG_CONTACT + ISK_CONTACT_ARG_COUNT)
#define ISK_BULGE_CLEARANCE_ARG_COMPOSITION \
  (ISK_BULGE_CLEARANCE_ARG_FIELDS + ISK_FIELD_ARG_COUNT)
#define ISK_BULGE_CLEARANCE_ARG_OUTPUT \
  (ISK_BULGE_CLEARANCE_ARG_COMPOSITION + ISK_COMPOSITION_ARG_COUNT)

#endif  // ISK_KERNELS_ABI_H
