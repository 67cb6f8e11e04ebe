// Per-joint parameters of implicit skinning saved with a rig: a small JSON
// file next to the asset ("CesiumMan.glb" -> "CesiumMan.glb.isk.json",
// rigParamsPathFor), loaded by isk-skin and the demo when present.
//
// Format (version 1; every key optional, unknown keys are errors):
//
//   {
//     "format": "isk-params",
//     "version": 1,
//     "defaults": {                // every joint not overridden below
//       "operator": "auto",        // auto | union | blend | bulge
//       "samples": 50,             // Poisson-disk samples per part, 1..100000
//       "bulge_strength": 1.0,     // [0, 1], joints whose operator is bulge
//       "blend_theta": 0.0         // [0, pi/4] rad, joints whose operator is
//       blend
//     },
//     "joints": {                  // overrides by joint name
//       "elbow": { "operator": "blend", "blend_theta": 0.2 },
//       "finger_1": { "operator": "bulge", "bulge_strength": 0.5,
//                     "samples": 80 },
//       "wrist": { "operator": "blend",
//                  "theta_curve": [0.785, 0.6, 0.3, 0.6, 0.785] },
//       "wing_membrane": { "tracked": false }
//     }
//   }
//
// "operator" in "defaults" may be "auto": the union, with the blend at the
// limb joints (CompositionOptions::limb_operator). Per joint, "operator" is
// the composition operator at the joint (the joint where the
// joint's bone meets its parent's, section 4.2); "samples" the Poisson-disk
// target of the joint's own part; "bulge_strength" and "blend_theta" shape
// the joint's default controller (Figure 7) and need that joint's operator
// to be bulge or blend respectively (a joint without an operator of its own
// under "auto" may take blend_theta: if it is not a limb joint, the
// composition warns that the controller has no effect); "theta_curve"
// replaces the controller
// by theta samples (radians in [0, pi/4]) taken uniformly over the angle
// alpha in [0, pi] between the two fields' gradients (at least 2 samples),
// and excludes the two keys before it; "tracked": false leaves the joint's
// part where geometric skinning puts it (ImplicitFieldsOptions::
// untracked_joints: a part the fields cannot hold). Errors are isk::Error
// (kInvalidArgument) naming the file, the joint and the key.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "isk/fields/composition_operator.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/rig/skeleton.hpp"

namespace isk {

struct JointParams {
  std::optional<CompositionOperator> op;
  std::optional<int> samples;
  std::optional<double> bulge_strength;
  std::optional<double> blend_theta;
  std::optional<std::vector<float>> theta_curve;
  std::optional<bool> tracked;  // false: the part stays on skinning

  bool operator==(const JointParams& other) const;
};

struct RigParams {
  CompositionOperator default_operator = CompositionOperator::kUnion;
  // The limb joints' operator (CompositionOptions::limb_operator).
  std::optional<CompositionOperator> limb_operator =
      CompositionOperator::kBlend;
  int samples = 50;
  double bulge_strength = 1;
  double blend_theta = 0;
  std::map<std::string, JointParams> joints;  // by joint name

  bool operator==(const RigParams& other) const;
};

// Parses the JSON `text`; `file` names it in errors. With a skeleton, joint
// names are checked against it (an unknown name lists a few known ones).
// Also checks each joint's keys against its operator (see above).
RigParams parseRigParams(const std::string& text, const std::string& file,
                         const Skeleton* skeleton = nullptr);
// Reads and parses `path` (isk::Error kIo when it cannot be read).
RigParams loadRigParams(const std::string& path,
                        const Skeleton* skeleton = nullptr);
// The JSON text of `params` (every default written, the joints sorted by
// name), which parseRigParams reads back to an equal RigParams.
std::string formatRigParams(const RigParams& params);
// Writes formatRigParams to `path` (temporary file + rename); isk::Error
// kIo naming the path.
void saveRigParams(const std::string& path, const RigParams& params);

// Sets the composition and sampling of `options` from `params`: default
// operator, controllers and samples, per-joint operators, sample counts and
// controllers (a joint with a theta_curve, bulge_strength or blend_theta
// gets its own controller), and the untracked joints ("tracked": false).
void applyRigParams(const RigParams& params, ImplicitFieldsOptions* options);

// "<asset>.isk.json": the parameter file that goes with `asset_path`.
std::string rigParamsPathFor(const std::string& asset_path);

}  // namespace isk
