#include "field_pictures.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <thread>

#include "isk/core/stopwatch.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/skinning.hpp"

namespace isk::samples {

void parallelRows(int count, const std::function<void(int, int)>& work) {
  const int threads = std::max(
      1, std::min<int>(count, static_cast<int>(std::max(
                                  1u, std::thread::hardware_concurrency()))));
  const int chunk = std::max(1, std::min(64, count / (threads * 4) + 1));
  std::atomic<int> next{0};
  auto worker = [&] {
    for (;;) {
      const int first = next.fetch_add(chunk);
      if (first >= count) return;
      work(first, std::min(count, first + chunk));
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
}

ImplicitFields buildFieldsWithProgress(const Rig& rig,
                                       const ImplicitFieldsOptions& options,
                                       const std::string& label,
                                       const std::string& warning_prefix) {
  ImplicitFieldsOptions with_progress = options;
  std::string last_stage;
  int last_tenth = -1;
  bool printed = false;
  with_progress.progress = [&](const char* stage, float fraction) {
    if (options.progress) options.progress(stage, fraction);
    const int tenth = static_cast<int>(fraction * 10.f);
    if (stage == last_stage && tenth == last_tenth) return;
    last_stage = stage;
    last_tenth = tenth;
    std::fprintf(stderr, "\r%s: %-10s %3d%%", label.c_str(), stage, tenth * 10);
    printed = true;
  };
  ImplicitFields fields;
  try {
    fields = buildImplicitFields(rig, with_progress);
  } catch (...) {
    if (printed) std::fprintf(stderr, "\n");
    throw;
  }
  if (printed) std::fprintf(stderr, "\n");
  for (const std::string& warning : fields.warnings) {
    std::cerr << warning_prefix << warning << "\n";
  }
  return fields;
}

TransformList clipSkinning(const Skeleton& skeleton, const AnimationClip& clip,
                           double seconds) {
  return skinningTransforms(
      skeleton,
      globalTransforms(skeleton, clip.sampleLocal(skeleton, seconds)));
}

Matrix3Xf dqsPositions(const Rig& rig, const TransformList& skinning) {
  Matrix3Xf positions, normals;
  SkinningJob job;
  job.method = SkinningMethod::kDualQuaternion;
  job.rest_positions = &rig.mesh.positions;
  job.rest_normals = &rig.mesh.normals;
  job.weights = &rig.weights;
  job.skinning = &skinning;
  job.out_positions = &positions;
  job.out_normals = &normals;
  job.run();
  return positions;
}

SliceView makeSliceView(const Rig& rig, const TransformList& skinning,
                        const Matrix3Xf& positions, int size) {
  const Skeleton& skeleton = rig.skeleton;
  const TransformList bind_globals = skeleton.bindGlobals();
  SliceView view;
  for (int pass = 0; pass < 2 && view.joints.empty(); ++pass) {
    for (int j = 0; j < skeleton.jointCount(); ++j) {
      if (pass == 0 && !skeleton.joints[j].is_skin_joint) continue;
      view.joints.push_back(
          (skinning[j] * bind_globals[j].translation()).cast<double>());
    }
  }
  view.plane = fitSlicePlane(view.joints, positions, size);
  view.section = meshSection(view.plane, positions, rig.mesh.triangles);
  for (const Eigen::Vector3d& j : view.joints) {
    view.joint_dots.push_back(view.plane.toImage(j));
  }
  return view;
}

SliceEvaluator::SliceEvaluator(const ImplicitFields& fields,
                               const TransformList& skinning,
                               const SlicePlane& plane)
    : fields_(fields), skinning_(skinning), plane_(plane) {
  for (const BoneField& field : fields.fields) {
    to_bind_.push_back(
        skinning[field.joint].cast<double>().inverse(Eigen::Affine));
  }
}

std::vector<float> SliceEvaluator::baked(int field) {
  const auto start = std::chrono::steady_clock::now();
  FieldGridSet single;
  const FieldGridSet* set = &fields_.grids;
  if (field != kComposed) {
    single.resolution = fields_.grids.resolution;
    single.grids.push_back(fields_.grids.grids[field]);
    set = &single;
  }
  std::vector<float> values(pixelCount(), 0.f);
  parallelRows(plane_.height, [&](int first, int last) {
    const Matrix4Xf out = evaluateComposedField(
        *set, skinning_, rowCentres(first, last),
        field == kComposed ? &fields_.composition : nullptr);
    const size_t offset = static_cast<size_t>(first) * plane_.width;
    for (Eigen::Index p = 0; p < out.rows(); ++p) {
      values[offset + p] = out(p, 0);
    }
  });
  baked_ms_ += millisecondsSince(start);
  return values;
}

std::vector<float> SliceEvaluator::analytic(int field) {
  const auto start = std::chrono::steady_clock::now();
  const int count = static_cast<int>(fields_.fields.size());
  const int lo = field == kComposed ? 0 : field;
  const int hi = field == kComposed ? count : field + 1;
  std::vector<float> values(pixelCount(), 0.f);
  const std::vector<float> joint_angles =
      pairJointAngles(fields_.composition, fields_.grids, skinning_);
  parallelRows(plane_.height, [&](int first, int last) {
    const Matrix3Xf points = rowCentres(first, last);
    const size_t offset = static_cast<size_t>(first) * plane_.width;
    for (Eigen::Index p = 0; p < points.rows(); ++p) {
      const Eigen::Vector3d x = points.row(p).transpose().cast<double>();
      std::vector<Eigen::Vector4d> samples(count, Eigen::Vector4d::Zero());
      for (int i = lo; i < hi; ++i) {
        double value = 0;
        Eigen::Vector3d gradient;
        fields_.fields[i].evaluate(to_bind_[i] * x, value, gradient);
        samples[i][0] = value;
        // Back to the posed frame: the transpose of the linear part.
        samples[i].tail<3>() = to_bind_[i].linear().transpose() * gradient;
      }
      values[offset + p] = static_cast<float>(
          composeExact(fields_.composition, samples, joint_angles)[0]);
    }
  });
  analytic_ms_ += millisecondsSince(start);
  return values;
}

size_t SliceEvaluator::pixelCount() const {
  return static_cast<size_t>(plane_.width) * plane_.height;
}

Matrix3Xf SliceEvaluator::rowCentres(int first, int last) const {
  Matrix3Xf points(static_cast<Eigen::Index>(last - first) * plane_.width, 3);
  for (int y = first; y < last; ++y) {
    for (int x = 0; x < plane_.width; ++x) {
      points.row(static_cast<Eigen::Index>(y - first) * plane_.width + x) =
          plane_.pixelCentre(x, y).cast<float>().transpose();
    }
  }
  return points;
}

SliceStats writeSlicePicture(const std::string& path,
                             const std::vector<float>& values,
                             const SliceView& view) {
  const SliceStats stats = sliceStats(values);
  const Image image = renderSlice(values, view.plane.width, view.plane.height,
                                  view.section, view.joint_dots);
  writePng(path, image);
  return stats;
}

SliceStats writeComposedPicture(const std::string& path, const Rig& rig,
                                const ImplicitFields& fields,
                                const TransformList& skinning,
                                const Matrix3Xf& positions, int size) {
  const SliceView view = makeSliceView(rig, skinning, positions, size);
  SliceEvaluator evaluator(fields, skinning, view.plane);
  return writeSlicePicture(path, evaluator.baked(SliceEvaluator::kComposed),
                           view);
}

}  // namespace isk::samples
