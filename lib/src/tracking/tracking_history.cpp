#include "isk/tracking/tracking_history.hpp"

#include <algorithm>
#include <cmath>

namespace isk {

const char* trackingModeName(TrackingMode mode) {
  return mode == TrackingMode::kHistory ? "history" : "2013";
}

float largestRelativeTurnDegrees(const std::vector<int>& parents,
                                 const TransformList& from,
                                 const TransformList& to) {
  const size_t joints = std::min({parents.size(), from.size(), to.size()});
  double largest = 0;
  for (size_t j = 0; j < joints; ++j) {
    const int p = parents[j];
    if (p < 0 || static_cast<size_t>(p) >= joints) continue;
    // The joint's transform relative to its parent at each pose, and the
    // change between them; its rotation's angle (a polar decomposition:
    // bind matrices may scale).
    const Eigen::Matrix3d a =
        (from[p].linear().inverse() * from[j].linear()).cast<double>();
    const Eigen::Matrix3d b =
        (to[p].linear().inverse() * to[j].linear()).cast<double>();
    const Eigen::Matrix3d change = a.inverse() * b;
    Eigen::Affine3d change_transform = Eigen::Affine3d::Identity();
    change_transform.linear() = change;
    const Eigen::Matrix3d r = change_transform.rotation();
    const double cosine = std::clamp((r.trace() - 1.0) / 2.0, -1.0, 1.0);
    largest = std::max(largest, std::acos(cosine) * 180.0 / M_PI);
  }
  return static_cast<float>(largest);
}

TrackingHistory::TrackingHistory(std::vector<int> parents, float reset_degrees)
    : parents_(std::move(parents)), reset_degrees_(reset_degrees) {}

bool TrackingHistory::next(const TransformList& pose) {
  const bool from_history =
      has_last_ && last_.size() == pose.size() &&
      largestRelativeTurnDegrees(parents_, last_, pose) <= reset_degrees_;
  last_ = pose;
  has_last_ = true;
  return from_history;
}

}  // namespace isk
