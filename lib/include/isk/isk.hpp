// isk: implicit skinning (Vaillant et al., "Implicit Skinning: Real-Time
// Skin Deformation with Contact Modeling", SIGGRAPH 2013) with its per-frame
// work in OpenCL. This umbrella header includes the whole public API of the
// isk library, folder by folder in pipeline order: core <- rig <- skinning,
// fields (paper section 4) <- tracking (section 5) <- the skinners; cl/ holds
// the device twins of each stage, tools/ procedural rigs and measures. The
// importer and file writers (isk/io/, library isk::io) are not included:
// runtime users need not link Assimp.
#pragma once

#include "isk/cl/field_evaluation.hpp"
#include "isk/cl/runtime.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/cl/surface_tracking.hpp"
#include "isk/core/dual_quaternion.hpp"
#include "isk/core/error.hpp"
#include "isk/core/mesh.hpp"
#include "isk/core/one_ring.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/core/surface_orientation.hpp"
#include "isk/core/types.hpp"
#include "isk/core/validation.hpp"
#include "isk/core/vertex_normals.hpp"
#include "isk/fields/bone_field.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/fields/bone_samples.hpp"
#include "isk/fields/composition_operator.hpp"
#include "isk/fields/field_cache.hpp"
#include "isk/fields/field_composition.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/field_grid.hpp"
#include "isk/fields/hrbf.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_crowd.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/rig/pose_anchor.hpp"
#include "isk/rig/rig.hpp"
#include "isk/rig/skeleton.hpp"
#include "isk/rig/skin_weights.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/skinning/skinning.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/procedural.hpp"
#include "isk/tools/self_intersection.hpp"
#include "isk/tools/skin_quality.hpp"
#include "isk/tools/subdivide.hpp"
#include "isk/tracking/surface_tracking.hpp"
