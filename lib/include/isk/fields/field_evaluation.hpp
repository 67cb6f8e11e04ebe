// Evaluation of the baked fields at posed points, CPU reference: each field's
// value and gradient, and the composed field (Vaillant et al. 2013, section
// 4.2, eq. 3).
//
// A field follows its joint rigidly: a posed point x is taken back to the
// field's bone frame by (skinning[joint] * bone_to_model)^-1 and sampled
// there (isk/fields/field_grid.hpp); its gradient comes back to model space by
// the transpose of that inverse's linear part (the rotation for a rigid pose).
//
// Composition (isk/fields/field_composition.hpp): the max of every field and of
// every blend or bulge pair of the character's Composition; without one, the
// union of all fields (max; the gradient is the largest field's). Only fields
// whose posed bounding sphere contains the point are sampled (broad phase).
// The OpenCL evaluation (isk/cl/field_evaluation.hpp) does the same job.
#pragma once

#include <vector>

#include "isk/core/types.hpp"
#include "isk/core/validation.hpp"
#include "isk/fields/field_composition.hpp"
#include "isk/fields/field_grid.hpp"

namespace isk {

// #rows by 4 float: value, gradient x y z.
using Matrix4Xf = Eigen::Matrix<float, Eigen::Dynamic, 4, Eigen::RowMajor>;

// Model-space -> bone-frame transform of every field for a pose (#fields),
// from the skinning transforms (#joints).
std::vector<Eigen::Affine3f> fieldTransforms(const FieldGridSet& fields,
                                             const TransformList& skinning);
// Each field's bounding sphere (fieldBoundingSphere) in model space for the
// model -> bone transforms `to_bone` (#fields): centre xyz, w = squared
// radius (scaled by the transform's largest stretch).
std::vector<Eigen::Vector4f> posedFieldSpheres(
    const FieldGridSet& fields, const std::vector<Eigen::Affine3f>& to_bone);

// The composed field of one pose, sampled one point at a time: the pose's
// field transforms, posed bounding spheres and pair joint angles are
// computed once at construction. The fields and composition must outlive it.
// FieldEvaluationJob and the surface tracking reference sample through it.
class ComposedFieldSampler {
 public:
  // `composition` may be null (union of all fields). No validation: use
  // FieldEvaluationJob::validate() first.
  ComposedFieldSampler(const FieldGridSet& fields,
                       const TransformList& skinning,
                       const Composition* composition);
  // Value and model-space gradient of the composed field at x. `per_field`
  // (when given) receives #fields samples (0 for culled fields).
  Eigen::Vector4f sample(const Eigen::Vector3f& x,
                         Eigen::Vector4f* per_field = nullptr) const;
  // The same restricted to the fields `subset[0..subset_count)` (indices,
  // ascending; masked with `mask`): for points that no other field's
  // support box can hold. `per_field` (required) receives #fields samples,
  // 0 for the fields not sampled.
  Eigen::Vector4f sampleSubset(const Eigen::Vector3f& x, const int* subset,
                               int subset_count, int mask,
                               Eigen::Vector4f* per_field) const;
  // Whether x lies in field i's support box (where its grid is sampled).
  bool insideBox(int i, const Eigen::Vector3f& x) const;
  // Posed bounding sphere of each field (centre, squared radius).
  const std::vector<Eigen::Vector4f>& spheres() const { return spheres_; }
  // Model -> bone transform of each field at the pose.
  const std::vector<Eigen::Affine3f>& toBone() const { return to_bone_; }
  // #fields of the FieldGridSet.
  int fieldCount() const { return fields_->fieldCount(); }

 private:
  Eigen::Vector4f sampleField(int i, const Eigen::Vector3f& x) const;
  Eigen::Vector4f composePairs(const Eigen::Vector4f* samples,
                               Eigen::Vector4f best) const;

  const FieldGridSet* fields_;
  const Composition* composition_;
  std::vector<Eigen::Affine3f> to_bone_;
  std::vector<Eigen::Vector4f> spheres_;
  std::vector<float> joint_angles_;
};

// The composed field (and optionally every field) at many posed points: the
// CPU reference of ClFieldEvaluation. The pointed-to inputs must outlive
// run().
struct FieldEvaluationJob {
  const FieldGridSet* fields = nullptr;
  const TransformList* skinning = nullptr;  // #joints
  const Matrix3Xf* points = nullptr;        // #P by 3, model space
  // Built for these fields (buildComposition); nullptr: union of all fields.
  const Composition* composition = nullptr;
  Matrix4Xf* out_composed = nullptr;  // resized to #P by 4
  // Optional: resized to (#P * #fields) by 4, row p * #fields + i.
  Matrix4Xf* out_per_field = nullptr;

  // Names the first missing input or mismatched size (pose length, points
  // shape, a composition built for other fields).
  Validation validate() const;
  // Throws isk::Error(kInvalidArgument) when validate() fails.
  void run() const;
};

// The composed field at posed points, #P by 4 (FieldEvaluationJob in one
// call). Throws isk::Error(kInvalidArgument) on inconsistent input.
Matrix4Xf evaluateComposedField(const FieldGridSet& fields,
                                const TransformList& skinning,
                                const Matrix3Xf& points,
                                const Composition* composition = nullptr);

// Every vertex's value of the composed field at the bind pose (the iso value
// it is projected back to while animating), #V. `outside` (when given)
// receives the vertices outside every field's support (value 0).
// `rest_positions`: #V by 3, model space. Throws isk::Error(kInvalidArgument)
// like evaluateComposedField.
std::vector<float> computeIsoValues(const FieldGridSet& fields,
                                    const Matrix3Xf& rest_positions,
                                    const Composition* composition,
                                    std::vector<int>* outside = nullptr);

}  // namespace isk
