// Pictures of a rig's implicit fields in a plane along its skeleton, shared
// by isk-field-slices and the demo: building the fields with progress on
// stderr, the posed mesh, the plane and what is drawn over the field (mesh
// section, joints), the fields evaluated at the pixels (baked grids or
// analytic), and the PNG.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/field_grid.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/rig.hpp"
#include "slice_image.hpp"
#include "slice_plane.hpp"

namespace isk::samples {

// Runs work(first, last) over [0, count) in row chunks on every hardware
// thread.
void parallelRows(int count, const std::function<void(int, int)>& work);

// isk::buildImplicitFields with its progress on stderr ("\r<label>: <stage>
// NN%", one update per stage and tenth, the line ended when done or on an
// error) and then each warning of the build on its own line, prefixed with
// `warning_prefix`.
ImplicitFields buildFieldsWithProgress(const Rig& rig,
                                       const ImplicitFieldsOptions& options,
                                       const std::string& label,
                                       const std::string& warning_prefix);

// The skinning transforms of `clip` at `seconds` (absolute clip time).
TransformList clipSkinning(const Skeleton& skeleton, const AnimationClip& clip,
                           double seconds);

// The rest mesh deformed by dual quaternion skinning on the CPU reference
// (the geometric skinning the implicit skinning starts from).
Matrix3Xf dqsPositions(const Rig& rig, const TransformList& skinning);

// What a picture of the fields at a pose is drawn in and over.
struct SliceView {
  SlicePlane plane;
  // The joints the plane follows: the skin joints (all joints if the rig
  // flags none), where the pose puts them, and their projections.
  std::vector<Eigen::Vector3d> joints;
  std::vector<Eigen::Vector2d> joint_dots;
  std::vector<Segment2> section;  // the posed mesh cut by the plane
};

// The view of `rig` posed by `skinning`, its mesh at `positions` (posed
// the same way), in an image whose longer side is `size` pixels. Throws
// isk::Error (see fitSlicePlane).
SliceView makeSliceView(const Rig& rig, const TransformList& skinning,
                        const Matrix3Xf& positions, int size);

// Evaluates the fields at every pixel centre of the plane, image rows
// spread over the hardware threads; `field` is an index into the fields, or
// kComposed for the composed field. Baked: the grids through
// isk::FieldEvaluationJob; analytic: each BoneField (HRBF through t_r, in
// double) at the point taken back to the bind pose by its joint's skinning
// transform, composed by the union (max). Values are row-major, top row
// first.
class SliceEvaluator {
 public:
  static constexpr int kComposed = -1;

  // Keeps references to all three.
  SliceEvaluator(const ImplicitFields& fields, const TransformList& skinning,
                 const SlicePlane& plane);

  std::vector<float> baked(int field);
  std::vector<float> analytic(int field);

  // Time spent so far in baked() and analytic().
  double bakedMs() const { return baked_ms_; }
  double analyticMs() const { return analytic_ms_; }

 private:
  size_t pixelCount() const;
  // Pixel centres of image rows [first, last), row-major.
  Matrix3Xf rowCentres(int first, int last) const;

  const ImplicitFields& fields_;
  const TransformList& skinning_;
  const SlicePlane& plane_;
  std::vector<Eigen::Affine3d> to_bind_;
  double baked_ms_ = 0, analytic_ms_ = 0;
};

// Paints `values` (one per pixel of view.plane) with the mesh section and
// the joints (renderSlice) and writes the PNG to `path`; returns the
// values' statistics. Throws isk::Error(kIo).
SliceStats writeSlicePicture(const std::string& path,
                             const std::vector<float>& values,
                             const SliceView& view);

// The whole picture of the composed baked field of `fields` for `rig` posed
// by `skinning` (its mesh at `positions`), longer side `size` pixels,
// written to `path`.
SliceStats writeComposedPicture(const std::string& path, const Rig& rig,
                                const ImplicitFields& fields,
                                const TransformList& skinning,
                                const Matrix3Xf& positions, int size);

}  // namespace isk::samples
