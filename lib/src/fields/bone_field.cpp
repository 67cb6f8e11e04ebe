#include "isk/fields/bone_field.hpp"

#include <algorithm>
#include <cmath>

#include "isk/core/error.hpp"

namespace isk {
namespace {

Eigen::Isometry3d boneFrame(const BoneSegment& segment) {
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.translation() = segment.start;
  if (segment.degenerate) return frame;
  const Eigen::Vector3d x = segment.direction();
  // Any unit vector orthogonal to x; pick the axis least aligned with it.
  Eigen::Vector3d helper = Eigen::Vector3d::UnitY();
  if (std::abs(x.y()) > std::abs(x.z())) helper = Eigen::Vector3d::UnitZ();
  if (std::abs(x.dot(helper)) > 0.9) helper = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d y = helper.cross(x).normalized();
  const Eigen::Vector3d z = x.cross(y);
  frame.linear().col(0) = x;
  frame.linear().col(1) = y;
  frame.linear().col(2) = z;
  return frame;
}

}  // namespace

BoneField fitBoneField(const Skeleton& skeleton,
                       const Matrix3Xf& mesh_positions,
                       const BonePartition& partition,
                       const BoneSamples& samples,
                       std::vector<std::string>* warnings) {
  const int joint = samples.joint;
  if (joint < 0 || joint >= skeleton.jointCount() ||
      joint >= static_cast<int>(partition.segments.size()))
    throw Error(ErrorCode::kInvalidArgument,
                "fitBoneField: joint " + std::to_string(joint) +
                    " is not a joint of the skeleton");
  const std::string what = "joint '" + skeleton.joints[joint].name + "'";
  const HermiteSamples all = samples.all();
  if (all.size() < 4)
    throw Error(ErrorCode::kInvalidArgument,
                what + ": " + std::to_string(all.size()) +
                    " samples, at least 4 are needed to fit a field");

  BoneField field;
  field.joint = joint;
  field.segment = partition.segments[joint];
  field.hrbf = Hrbf::fit(all, what, warnings);
  for (const auto& p : all.positions)
    field.radius = std::max(field.radius, field.segment.distance(p));
  if (!(field.radius > 0))
    throw Error(ErrorCode::kInvalidArgument,
                what +
                    ": every sample lies on the bone; the field has no "
                    "support");
  field.bone_to_model = boneFrame(field.segment);
  field.guard_radius = field.radius;
  for (const auto& p : all.positions)
    field.guard_radius =
        std::max(field.guard_radius, field.segment.distance(p));
  if (joint < static_cast<int>(partition.part_vertices.size()))
    for (int v : partition.part_vertices[joint])
      field.guard_radius =
          std::max(field.guard_radius,
                   field.segment.distance(
                       mesh_positions.row(v).transpose().cast<double>()));

  // The guard makes f vanish beyond R + r from the segment (x from 0 to L
  // in the bone frame).
  const Eigen::Vector3d grow =
      Eigen::Vector3d::Constant(field.guard_radius + field.radius);
  field.support_box = Eigen::AlignedBox3d(
      -grow, Eigen::Vector3d(field.segment.length(), 0, 0) + grow);
  return field;
}

void BoneField::guard(const Eigen::Vector3d& x, double& distance,
                      Eigen::Vector3d& gradient) const {
  const Eigen::Vector3d nearest =
      segment.start +
      std::clamp(segment.along(x), 0.0, 1.0) * (segment.end - segment.start);
  const Eigen::Vector3d away = x - nearest;
  const double rho = away.norm();
  if (rho - guard_radius > distance) {
    distance = rho - guard_radius;
    gradient = rho > 0 ? Eigen::Vector3d(away / rho) : Eigen::Vector3d::Zero();
  }
}

void BoneField::guardedDistance(const Eigen::Vector3d& x, double& distance,
                                Eigen::Vector3d& gradient) const {
  hrbf.evaluate(x, distance, gradient);
  guard(x, distance, gradient);
}

void BoneField::evaluate(const Eigen::Vector3d& x, double& value,
                         Eigen::Vector3d& gradient) const {
  if (!support_box.contains(bone_to_model.inverse() * x)) {
    value = 0;
    gradient.setZero();
    return;
  }
  double d;
  Eigen::Vector3d grad_d;
  guardedDistance(x, d, grad_d);
  value = reparameterize(d, radius);
  gradient = reparameterizeDerivative(d, radius) * grad_d;
}

double BoneField::value(const Eigen::Vector3d& x) const {
  double v;
  Eigen::Vector3d g;
  evaluate(x, v, g);
  return v;
}

}  // namespace isk
