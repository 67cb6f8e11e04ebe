// kernels/abi.h, and compile-time checks that the public types the host
// hands to the kernels hold the same values.
#pragma once

#include "abi.h"
#include "isk/cl/field_evaluation.hpp"
#include "isk/core/one_ring.hpp"
#include "isk/fields/composition_operator.hpp"
#include "isk/tracking/surface_tracking.hpp"

namespace isk::detail {

static_assert(static_cast<int>(TrackState::kMarching) == ISK_TRACK_MARCHING);
static_assert(static_cast<int>(TrackState::kConverged) == ISK_TRACK_CONVERGED);
static_assert(static_cast<int>(TrackState::kContact) == ISK_TRACK_CONTACT);
static_assert(static_cast<int>(TrackState::kLost) == ISK_TRACK_LOST);
static_assert(static_cast<int>(TrackState::kUntracked) == ISK_TRACK_UNTRACKED);
static_assert(static_cast<int>(TrackState::kCrease) == ISK_TRACK_CREASE);
static_assert(static_cast<int>(RingKind::kClosed) == ISK_RING_CLOSED);
static_assert(static_cast<int>(RelaxationRule::kFixed) == ISK_RULE_FIXED);
static_assert(TrackingMesh::kMaxPartners == ISK_MAX_PARTNERS);
static_assert(FieldNeighbourhoods::kPartner == ISK_NEIGHBOUR_PARTNER);
static_assert(ClFieldEvaluation::kParamStride == ISK_FIELD_PARAM_STRIDE);
static_assert(kControllerSamples == ISK_CONTROLLER_SAMPLES);

}  // namespace isk::detail
