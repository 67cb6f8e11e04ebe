#include "isk/rig/animation.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace isk {
namespace {

// Index i and fraction a such that the value at t lies between keys i and i+1.
void bracket(const std::vector<double>& times, double t, size_t& i, float& a) {
  if (times.size() < 2 || t <= times.front()) {
    i = 0;
    a = 0.f;
    return;
  }
  if (t >= times.back()) {
    i = times.size() - 2;
    a = 1.f;
    return;
  }
  i = static_cast<size_t>(std::upper_bound(times.begin(), times.end(), t) -
                          times.begin()) -
      1;
  const double span = times[i + 1] - times[i];
  a = span > 0 ? static_cast<float>((t - times[i]) / span) : 0.f;
}

Eigen::Vector3f sampleVector(const std::vector<double>& times,
                             const std::vector<Eigen::Vector3f>& keys,
                             double t) {
  if (keys.size() == 1) return keys[0];
  size_t i;
  float a;
  bracket(times, t, i, a);
  return (1.f - a) * keys[i] + a * keys[i + 1];
}

Eigen::Quaternionf sampleRotation(const std::vector<double>& times,
                                  const std::vector<Eigen::Quaternionf>& keys,
                                  double t) {
  if (keys.size() == 1) return keys[0].normalized();
  size_t i;
  float a;
  bracket(times, t, i, a);
  // Eigen's slerp takes the shorter arc.
  return keys[i].normalized().slerp(a, keys[i + 1].normalized());
}

bool isFinite(const Eigen::Vector3f& v) { return v.allFinite(); }
bool isFinite(const Eigen::Quaternionf& q) { return q.coeffs().allFinite(); }

template <typename Key>
Validation validateTrack(const std::vector<double>& times,
                         const std::vector<Key>& keys, const char* what) {
  if (times.size() != keys.size()) {
    return Validation::fail(std::string(what) +
                            " times and keys differ in count");
  }
  for (size_t k = 0; k < times.size(); ++k) {
    if (!std::isfinite(times[k]) || (k > 0 && times[k] < times[k - 1])) {
      return Validation::fail(std::string(what) + " key " + std::to_string(k) +
                              " has a non-finite or decreasing time");
    }
    if (!isFinite(keys[k])) {
      return Validation::fail(std::string(what) + " key " + std::to_string(k) +
                              " is not finite");
    }
  }
  return Validation::ok();
}

}  // namespace

TransformList AnimationClip::sampleLocal(const Skeleton& skeleton,
                                         double t) const {
  TransformList locals(skeleton.joints.size());
  for (size_t j = 0; j < locals.size(); ++j)
    locals[j] = skeleton.joints[j].rest_local;
  t = std::clamp(t, start, start + duration);
  for (const JointChannel& channel : channels) {
    if (channel.joint < 0 || channel.joint >= skeleton.jointCount()) continue;
    // Missing tracks keep the rest local's component (decomposed once).
    const Eigen::Affine3f& rest = skeleton.joints[channel.joint].rest_local;
    Eigen::Matrix3f rotation, scaling;
    rest.computeRotationScaling(&rotation, &scaling);
    Eigen::Vector3f translation = rest.translation();
    Eigen::Quaternionf q(rotation);
    Eigen::Vector3f scale = scaling.diagonal();
    if (!channel.translations.empty()) {
      translation =
          sampleVector(channel.translation_times, channel.translations, t);
    }
    if (!channel.rotations.empty()) {
      q = sampleRotation(channel.rotation_times, channel.rotations, t);
    }
    if (!channel.scales.empty()) {
      scale = sampleVector(channel.scale_times, channel.scales, t);
    }
    Eigen::Affine3f local = Eigen::Affine3f::Identity();
    local.translate(translation).rotate(q).scale(scale);
    locals[channel.joint] = local;
  }
  return locals;
}

Validation AnimationClip::validate(const Skeleton& skeleton) const {
  if (!std::isfinite(start) || !std::isfinite(duration) || duration < 0) {
    return Validation::fail("invalid start or duration");
  }
  for (size_t c = 0; c < channels.size(); ++c) {
    const JointChannel& channel = channels[c];
    if (channel.joint < 0 || channel.joint >= skeleton.jointCount()) {
      return Validation::fail("channel " + std::to_string(c) +
                              " targets no joint of the skeleton");
    }
    const std::string where =
        "channel of joint '" + skeleton.joints[channel.joint].name + "': ";
    for (Validation v :
         {validateTrack(channel.translation_times, channel.translations,
                        "translation"),
          validateTrack(channel.rotation_times, channel.rotations, "rotation"),
          validateTrack(channel.scale_times, channel.scales, "scale")}) {
      if (!v) return Validation::fail(where + v.reason());
    }
  }
  return Validation::ok();
}

AnimationClip makeBendClip(const Skeleton& skeleton, float max_angle_radians,
                           double duration) {
  AnimationClip clip;
  clip.name = "bend";
  clip.start = 0.0;
  clip.duration = duration;
  const int n = skeleton.jointCount();
  // Bone direction of each joint in its own frame: towards its first child,
  // else continuing its parent's bone.
  std::vector<Eigen::Vector3f> direction(n, Eigen::Vector3f::Zero());
  for (int j = n - 1; j >= 0; --j) {
    const int parent = skeleton.joints[j].parent;
    if (parent >= 0 && direction[parent].isZero()) {
      const Eigen::Vector3f offset =
          skeleton.joints[j].rest_local.translation();
      if (offset.norm() > 0) direction[parent] = offset.normalized();
    }
  }
  for (int j = 0; j < n; ++j) {
    if (direction[j].isZero()) {
      const int parent = skeleton.joints[j].parent;
      const Eigen::Vector3f offset =
          skeleton.joints[j].rest_local.translation();
      direction[j] =
          (parent >= 0 && offset.norm() > 0)
              ? Eigen::Vector3f(
                    skeleton.joints[j].rest_local.linear().transpose() *
                    offset.normalized())
              : Eigen::Vector3f::UnitX();
    }
  }
  const int steps = 16;
  for (int j = 0; j < n; ++j) {
    // Roots carry the whole character: bending them would only swing it.
    if (skeleton.joints[j].parent < 0) continue;
    const Eigen::Vector3f d = direction[j];
    // The axis perpendicular to the bone closest to the joint's z axis.
    Eigen::Vector3f axis = d.cross(Eigen::Vector3f::UnitZ());
    if (axis.norm() < 1e-3f) axis = d.cross(Eigen::Vector3f::UnitY());
    axis.normalize();
    const Eigen::Affine3f& rest = skeleton.joints[j].rest_local;
    Eigen::Matrix3f rotation, scaling;
    rest.computeRotationScaling(&rotation, &scaling);
    JointChannel channel;
    channel.joint = j;
    for (int k = 0; k <= steps; ++k) {
      const double t = duration * k / steps;
      const float angle = max_angle_radians * static_cast<float>(k) / steps;
      channel.rotation_times.push_back(t);
      channel.rotations.push_back(
          Eigen::Quaternionf(rotation) *
          Eigen::Quaternionf(Eigen::AngleAxisf(angle, axis)));
    }
    clip.channels.push_back(std::move(channel));
  }
  return clip;
}

}  // namespace isk
