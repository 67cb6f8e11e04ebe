// The global field of a character (Vaillant et al. 2013, section 4.2,
// eq. 3): each joint combines the fields of its two bones with the operator
// chosen for it (isk/fields/composition_operator.hpp), and the global field is
// the max of every joint's composition and of every field.
//
// Joint pairs: the joint j whose bone has a field pairs that field with the
// field of its nearest ancestor that has one (the bone that ends at j: the
// upper arm at the elbow). The operator of the pair is the one chosen for
// joint j (by its name). A union pair adds nothing to the max of all fields,
// so only blend and bulge pairs are evaluated as pairs.
//
// At a point, a pair's theta comes from the angle alpha between its two
// fields' gradients through the pair's controller (Figure 7), alpha capped
// by the joint's rotation from its bind pose (the angle of the rotation
// taking the parent bone's skinning rotation to the child's): the paper
// notes that alpha is close to that rotation (Figure 6(a)), but where two
// parts meet, their rounded ends make gradients differ by 20 to 45 degrees
// even at rest, and the local angle alone would blend a straight limb into
// a bulge (3% of its radius on the procedural cylinder). With the cap, a
// joint at its bind rotation is a union whatever its parts' ends look like;
// once it turns, the local angle decides as in the paper. The gradient of
// the composition is dg/df1 grad f1 + dg/df2 grad f2 (the dependence of
// theta on the point is left out, as in the paper). A field whose gradient
// vanishes gives alpha = 0.
//
// Broad phase: each field has a bounding sphere of its support box; at a
// point only fields whose posed sphere contains it are sampled, and a pair
// only when both are.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "isk/fields/composition_operator.hpp"
#include "isk/fields/field_grid.hpp"
#include "isk/rig/skeleton.hpp"

namespace isk {

// Which operator each joint uses and how its theta is controlled.
struct CompositionOptions {
  // The operator of every joint not named in `joint_operators`...
  CompositionOperator default_operator = CompositionOperator::kUnion;
  // ... but for the limb joints (isk/fields/limb_joints.hpp: shoulders,
  // elbows, wrists, knees, ankles of mirrored limbs), which take this one
  // when set. The default, union with the blend at the limbs, is the
  // paper's advice and the "auto" choice of parseOperatorChoice.
  std::optional<CompositionOperator> limb_operator =
      CompositionOperator::kBlend;
  // Per-joint choices by joint name (the joint at which two bones meet: the
  // elbow's joint pairs the upper arm with the forearm).
  std::map<std::string, CompositionOperator> joint_operators;
  // Controllers (Figure 7): theta of the full blend at alpha = pi/4, and the
  // bulge strength in [0, 1] reached from alpha = pi/2 on.
  double blend_theta = 0;
  double bulge_strength = 1;
  // Per-joint controllers by joint name (sampled over alpha in [0, pi]);
  // they replace the defaults above for that joint.
  std::map<std::string, ThetaController> joint_controllers;
  int table_resolution = 128;  // operator tables, nodes per axis
};

// The operator choice by name: "auto" (union, blend at the limb joints),
// "union", "blend" or "bulge" (that operator at every joint) into
// `options`' default_operator and limb_operator; false for anything else.
bool parseOperatorChoice(const std::string& name, CompositionOptions* options);
// The name of `options`' choice above ("auto", "union", ...); a pair it
// cannot name is written "DEFAULT, LIMB at the limbs".
std::string operatorChoiceName(const CompositionOptions& options);

// Two neighbouring fields and their operator.
struct FieldPair {
  int joint = -1;  // the joint where the two bones meet (the child's)
  int field_a = -1, field_b = -1;  // indices into the field set: parent, child
  CompositionOperator op = CompositionOperator::kUnion;
  int controller = -1;  // index into Composition::controllers; -1 for union
  int table = -1;       // index into Composition::tables; -1 for union
};

// The operators of a character's joints, built by buildComposition for its
// FieldGridSet. Immutable, ready to upload.
struct Composition {
  std::vector<FieldPair> pairs;              // every joint pair, joint order
  std::vector<int> blended_pairs;            // indices of the non-union pairs
  std::vector<ThetaController> controllers;  // kControllerSamples each
  std::vector<std::shared_ptr<const OperatorTable>> tables;  // used kinds
  int table_resolution = 128;
  std::vector<std::string> warnings;  // e.g. a named joint without a pair

  // The operator of the pair at joint j (union when j has none).
  CompositionOperator operatorAt(int joint) const;
  // Whether some pair composes with `op` (blend or bulge; the union: some
  // pair at all). A global controller setting (blend_theta,
  // bulge_strength) shapes nothing where its operator is not used.
  bool uses(CompositionOperator op) const;
  // Bytes of the operator tables (what the device holds for them).
  size_t tableBytes() const;
};

// Checks the options against the skeleton (joint names, ranges); the reason
// names the joint or the option.
Validation validateCompositionOptions(const Skeleton& skeleton,
                                      const CompositionOptions& options);

// Builds the composition of `fields` for `skeleton`. Throws
// isk::Error(kInvalidArgument) for a joint name that is not in the skeleton
// (listing a few that are), a controller with fewer than 2 samples or values
// outside [0, pi/4], bulge_strength outside [0, 1], blend_theta outside
// [0, pi/4] or a bad table resolution. A named joint that pairs no two fields
// is a warning. Operator tables come from sharedOperatorTable (baked once per
// process); `progress` reports their baking (0..1).
Composition buildComposition(
    const Skeleton& skeleton, const FieldGridSet& fields,
    const CompositionOptions& options = {},
    const std::function<void(float)>& progress = nullptr);

// A bounding sphere of a field's support box, bone frame: centre xyz and
// radius w (model units).
Eigen::Vector4f fieldBoundingSphere(const FieldGrid& grid);

// Each blend or bulge pair's joint rotation from its bind pose (radians, in
// [0, pi]; Composition::blended_pairs order) for the skinning transforms
// `skinning` (#joints): the cap of alpha above.
std::vector<float> pairJointAngles(const Composition& composition,
                                   const FieldGridSet& fields,
                                   const TransformList& skinning);

// Composes the samples of a pair (value, model-space gradient each) with
// its operator through its table and controller, alpha capped by
// `joint_angle` (pairJointAngles): value and gradient. The kernels do
// exactly this (kernels/fields/compose.cl: compose_pair).
Eigen::Vector4f composePair(const Composition& composition,
                            const FieldPair& pair, const Eigen::Vector4f& a,
                            const Eigen::Vector4f& b, float joint_angle);

// The composition of exact samples, one per field (#fields; value and
// model-space gradient, e.g. from the analytic fields): the max of all of
// them and of every blend or bulge pair with its operator evaluated directly
// (evaluateOperator, no table; theta through the pair's controller, alpha
// capped by `joint_angles`, from pairJointAngles). The reference the baked
// composition approximates.
Eigen::Vector4d composeExact(const Composition& composition,
                             const std::vector<Eigen::Vector4d>& samples,
                             const std::vector<float>& joint_angles);

// One line for reports: "union at every joint", or the joints per
// operator ("blend at 'elbow.L', 'elbow.R'; union elsewhere").
std::string describeComposition(const Composition& composition,
                                const Skeleton& skeleton);

}  // namespace isk
