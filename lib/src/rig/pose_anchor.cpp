#include "isk/rig/pose_anchor.hpp"

#include <algorithm>
#include <cmath>

namespace isk {

float anchorStep(float rest_diagonal) {
  if (!(rest_diagonal > 0.f) || !std::isfinite(rest_diagonal)) return 1.f;
  return std::exp2(std::ceil(std::log2(rest_diagonal)));
}

Eigen::Vector3f poseAnchor(const TransformList& skinning,
                           const std::vector<Eigen::Vector3f>& rest_centers,
                           float step) {
  if (skinning.empty() || skinning.size() != rest_centers.size() ||
      !(step > 0.f))
    return Eigen::Vector3f::Zero();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (size_t j = 0; j < skinning.size(); ++j)
    sum += skinning[j].cast<double>() * rest_centers[j].cast<double>();
  const Eigen::Vector3d mean = sum / static_cast<double>(skinning.size());
  if (!mean.allFinite() || mean.cwiseAbs().maxCoeff() < kAnchorFreeSteps * step)
    return Eigen::Vector3f::Zero();
  const Eigen::Vector3d steps = (mean / step).array().round();
  if (steps.cwiseAbs().maxCoeff() > 1e15) return Eigen::Vector3f::Zero();
  return (steps * static_cast<double>(step)).cast<float>();
}

std::vector<Eigen::Vector3f> restCenters(const Matrix3Xf& rest_positions,
                                         int joints) {
  const Eigen::Vector3f center =
      rest_positions.rows() == 0
          ? Eigen::Vector3f::Zero()
          : Eigen::Vector3f(0.5f * (rest_positions.colwise().minCoeff() +
                                    rest_positions.colwise().maxCoeff())
                                       .transpose());
  return std::vector<Eigen::Vector3f>(static_cast<size_t>(std::max(joints, 0)),
                                      center);
}

void subtractAnchor(const Eigen::Vector3f& anchor, TransformList& skinning) {
  for (Eigen::Affine3f& transform : skinning) transform.translation() -= anchor;
}

}  // namespace isk
